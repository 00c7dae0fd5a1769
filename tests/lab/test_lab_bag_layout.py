"""Pull-test bags: write -> read round trip with rosbags, sqlite3 and mcap."""
from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rosbags')

from rftgls_core.types import AnchorState  # noqa: E402
from rftgls_ros.lab import planar  # noqa: E402
from rftgls_ros.lab.bag_layout import (  # noqa: E402
    TOPICS,
    CameraCalibration,
    MarkerSetup,
    PullTest,
    PullTestMeta,
    Tracking,
    read_metadata,
    read_pull_test,
    write_pull_test,
)


def make_test(with_tracking: bool = True) -> PullTest:
    rng = np.random.default_rng(3)
    meta = PullTestMeta(
        test_id='rt-1', robot='prototype',
        medium={'name': 'glass_beads', 'xi_n': 3.8e5, 'mu_surf': 0.4, 'zeta': 0.33e6},
        pull='forward', initial_state=AnchorState.from_degrees(0.02, 1.0, -40.0, 0.0),
        phi_rad=0.0, synthetic=True, generator='pytest',
        markers=MarkerSetup(tank_in_world=(0.1, 0.05, 0.0), p_in_robot=(-0.02, -0.01, 0.0)),
        camera=CameraCalibration.simple(1280, 720, 1400.0))
    ft = np.arange(0.0, 2.0, 0.01)
    n = 40
    pt = np.arange(n) * 0.05
    pose = np.stack([-0.001 * np.arange(n), 0.02 - 0.0003 * np.arange(n),
                     np.radians(0.2 * np.arange(n))], axis=1)
    tracking = None
    if with_tracking:
        ok = np.ones((n + 2, 2), bool)
        ok[5, 1] = False        # robot marker lost
        ok[7, 0] = False        # tank marker lost
        M = np.tile(np.eye(4), (n + 2, 1, 1))
        M[:, 2, 3] = 0.6
        tracking = Tracking(t=np.arange(n + 2) * 0.05, ok=ok,
                            reprojection_px=np.where(ok, 0.1, np.nan),
                            out_of_plane_m=np.where(ok[:, 1], 1e-4, np.nan),
                            marker_poses={'tank': M, 'robot': M})
    return PullTest(meta=meta, t0_ns=1_700_000_000_000_000_000, force_t=ft,
                    tension_N=3.0 + rng.normal(0, 0.05, ft.size), phi_rad=np.full(ft.size, 0.01),
                    pose_t=pt, pose=pose, joint_t=ft[::10],
                    legs=np.tile(np.radians([-40.0, 0.0]), (ft[::10].size, 1)),
                    tracking=tracking, images=[(0.0, b'\x89PNG fake'), (0.5, b'\x89PNG 2')])


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_round_trip(tmp_path, storage):
    test = make_test()
    write_pull_test(tmp_path / 'bag', test, storage=storage)
    back = read_pull_test(tmp_path / 'bag', images=True)
    assert back.meta == test.meta
    assert back.t0_ns == test.t0_ns
    np.testing.assert_allclose(back.force_t, test.force_t, atol=1e-9)
    np.testing.assert_allclose(back.tension_N, test.tension_N, rtol=1e-12)
    np.testing.assert_allclose(back.phi_rad, test.phi_rad, atol=1e-12)
    np.testing.assert_allclose(back.pose_t, test.pose_t, atol=1e-9)
    np.testing.assert_allclose(back.pose, test.pose, atol=1e-12)
    np.testing.assert_allclose(back.legs, test.legs, atol=1e-12)
    assert back.images == test.images
    lost = back.tracking.lost_times()
    assert lost['robot'].tolist() == pytest.approx([0.25])
    assert lost['tank'].tolist() == pytest.approx([0.35])
    assert lost['p'].tolist() == pytest.approx([0.25, 0.35])
    np.testing.assert_allclose(back.tracking.marker_poses['robot'][0],
                               test.tracking.marker_poses['robot'][0], atol=1e-12)
    assert np.isnan(back.tracking.marker_poses['robot'][5]).all()   # lost: nothing invented
    assert read_metadata(tmp_path / 'bag') == test.meta


def test_bag_topics_and_custom_metadata(tmp_path):
    """Every topic is declared with its type; metadata is mirrored in metadata.yaml."""
    from rosbags.rosbag2 import Reader
    test = make_test()
    write_pull_test(tmp_path / 'bag', test, storage='mcap')
    with Reader(tmp_path / 'bag') as r:
        types = {c.topic: c.msgtype for c in r.connections}
    from ruamel.yaml import YAML
    info = YAML(typ='safe').load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    assert info['rosbag2_bagfile_information']['custom_data']['rftgls_lab.metadata'] \
        == test.meta.to_json()
    assert types == {t: TOPICS[t][0] for t in types}
    assert {'/lab/metadata', '/winch/tension', '/joint_states', '/lab/p_pose', '/lab/tracking',
            '/winch/height', '/lab/theta_b', '/winch/phi'} <= set(types)


def test_without_tracking_and_bad_bag(tmp_path):
    test = make_test(with_tracking=False)
    test.images = None
    write_pull_test(tmp_path / 'bag', test, storage='sqlite3')
    back = read_pull_test(tmp_path / 'bag')
    assert back.tracking is None and back.images is None
    with pytest.raises(ValueError, match='not a rftgls_lab.pull_test'):
        PullTestMeta.from_json('{"schema": "other"}')


def test_planar_helpers():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 3))
    b = rng.normal(size=(50, 3))
    np.testing.assert_allclose(planar.compose(planar.inverse(a), planar.compose(a, b)), b,
                               atol=1e-12)
    th = rng.uniform(-3, 3, 50)
    q = planar.quaternion_from_theta(th)
    np.testing.assert_allclose(planar.theta_from_quaternion(q), th, atol=1e-12)
    # capacity_node reads thetaB = asin(2 (qx qz - qw qy)) from the same quaternion
    small = th[np.abs(th) < math.pi / 2]
    qs = planar.quaternion_from_theta(small)
    np.testing.assert_allclose(np.arcsin(2 * (qs[:, 0] * qs[:, 2] - qs[:, 3] * qs[:, 1])), small,
                               atol=1e-12)


def test_bag_records_qos_and_static_frames_like_a_jazzy_recording(tmp_path):
    """metadata.yaml as `ros2 bag play` reads it: storage mcap, offered QoS per topic (the
    latched topics transient-local), and /tf_static with the bench's fixed frames."""
    import yaml
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    test = make_test()
    write_pull_test(tmp_path / 'bag', test)
    info = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    info = info['rosbag2_bagfile_information']
    assert info['storage_identifier'] == 'mcap'
    qos = {}
    for t in info['topics_with_message_count']:
        md = t['topic_metadata']
        profiles = md['offered_qos_profiles']
        profiles = yaml.safe_load(profiles) if isinstance(profiles, str) else profiles
        assert len(profiles) == 1, md['name']
        qos[md['name']] = profiles[0]
    assert set(qos) <= set(TOPICS) and {'/lab/metadata', '/tf_static', '/winch/tension'} <= set(qos)
    # rmw enums: reliability 1 = reliable; durability 1 = transient local, 2 = volatile
    for topic, q in qos.items():
        assert q['reliability'] in (1, 'reliable'), topic
        latched = topic in ('/lab/metadata', '/tf_static')
        assert q['durability'] in ((1, 'transient_local') if latched else (2, 'volatile')), topic
        assert q['depth'] == (1 if latched else 100)
    ts = get_typestore(Stores.ROS2_JAZZY)
    with Reader(tmp_path / 'bag') as r:
        conns = [c for c in r.connections if c.topic == '/tf_static']
        msgs = [ts.deserialize_cdr(raw, c.msgtype) for c, _, raw in r.messages(conns)]
    assert len(msgs) == 1
    tf = {(t.header.frame_id, t.child_frame_id): t.transform for t in msgs[0].transforms}
    assert set(tf) == {('lab_world', 'aruco_tank'), ('lab_world', 'camera_optical')}
    assert msgs[0].transforms[0].header.stamp.sec == test.t0_ns // 10**9
    tank = tf[('lab_world', 'aruco_tank')]
    assert (tank.translation.x, tank.translation.y, tank.translation.z) == (0.1, 0.0, 0.05)
    # theta 0: marker x = world x, marker z = world -y: +90 deg about world x.
    q = tank.rotation
    assert (q.x, q.y, q.z, q.w) == pytest.approx((math.sqrt(0.5), 0, 0, math.sqrt(0.5)))
    # The camera: tank marker 0.6 m in front of it (the fixture's T_cam_tank = translation z).
    cam = tf[('lab_world', 'camera_optical')]
    assert (cam.translation.x, cam.translation.y, cam.translation.z) == pytest.approx(
        (0.1, 0.6, 0.05))


def test_replay_latches_what_the_bag_says(tmp_path):
    from rosbags.rosbag2 import Reader

    from rftgls_ros.lab.replay import latched
    write_pull_test(tmp_path / 'bag', make_test())
    with Reader(tmp_path / 'bag') as r:
        by_topic = {c.topic: latched(c) for c in r.connections}
    assert by_topic.pop('/lab/metadata') and by_topic.pop('/tf_static')
    assert not any(by_topic.values())
