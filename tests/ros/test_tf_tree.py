"""state_publisher's transform math (rftgls_ros.tf_tree, ROS-free) against transforms worked
out by hand from the shipped MiniRQuad URDF (rftgls_core/data/minirquad.urdf: left proximal hip
at (0.03, 0.045, 0.01) m, left distal hip at (0.12, 0.055, 0.01) m, hip axes -y, imu_link at
(0.075, 0, 0.01) m, winch_link at base_link's origin), and against the core's own forward
kinematics (rftgls_core.description, a separate implementation)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_conventions import LEG_JOINT_NAMES
from rftgls_core.description import load_description, shipped_description
from rftgls_core.types import AnchorState
from rftgls_ros.tf_tree import (
    MOVING,
    TfTree,
    Transform,
    UrdfError,
    matrix_to_quat,
    moving_transforms,
    odom_to_anchor,
    odom_to_base,
    parse_urdf_joints,
    quat_to_matrix,
    static_transforms,
    tree_from,
)

URDF = shipped_description('minirquad').with_suffix('.urdf')


@pytest.fixture(scope='module')
def joints():
    return parse_urdf_joints(URDF.read_text())


def point(m: np.ndarray, p) -> np.ndarray:
    return (m @ np.array([*p, 1.0]))[:3]


def test_static_transforms_are_the_fixed_joints(joints):
    st = {t.child: t for t in static_transforms(joints)}
    assert set(st) == {'imu_link', 'winch_link'}
    assert st['imu_link'].parent == 'base_link'
    assert st['imu_link'].translation == pytest.approx((0.075, 0.0, 0.01), abs=1e-12)
    assert st['imu_link'].rotation == pytest.approx((0, 0, 0, 1), abs=1e-12)
    assert st['winch_link'].translation == pytest.approx((0, 0, 0), abs=1e-12)


def test_hip_at_90_deg_by_hand(joints):
    # Axis -y, value +90 deg: a rotation of -90 deg about +y, quaternion (0, -sin 45, 0, cos 45).
    # A leg hanging straight down at 0 deg, its point (0, 0, -L) in the leg frame, swings
    # forward: +L along x_B, at the hip's height (the paper's leg angle from -z_B).
    (t,) = moving_transforms(joints, ['leg_proximal_left'], [math.pi / 2])
    assert (t.parent, t.child) == ('base_link', 'left_proximal_leg')
    s = math.sqrt(0.5)
    assert t.rotation == pytest.approx((0.0, -s, 0.0, s), abs=1e-12)
    assert point(t.matrix(), (0, 0, -0.05)) == pytest.approx((0.08, 0.045, 0.01), abs=1e-12)


def test_leg_point_in_odom_by_hand(joints):
    h, theta_b, q, L = 0.04, math.radians(10.0), math.radians(30.0), 0.05
    tree = tree_from(static_transforms(joints),
                     [odom_to_base(h, theta_b), odom_to_anchor(h),
                      *moving_transforms(joints, ['leg_distal_left'], [q])])
    # In base_link: the distal hip plus the leg turned forward by q from -z_B.
    xb, yb, zb = 0.12 + L * math.sin(q), 0.055, 0.01 - L * math.cos(q)
    # In odom: x_B is (cos, 0, sin) theta_B (nose up), z_B is (-sin, 0, cos) theta_B, p at h.
    c, s = math.cos(theta_b), math.sin(theta_b)
    want = (xb * c - zb * s, yb, h + xb * s + zb * c)
    assert point(tree.to_root('left_distal_leg'), (0, 0, -L)) == pytest.approx(want, abs=1e-12)
    assert tree.root('left_distal_leg') == 'odom'
    # anchor: world-aligned axes at p = base_link's origin = winch_link's.
    assert tree.to_root('anchor')[:3, :3] == pytest.approx(np.eye(3), abs=1e-15)
    assert tree.to_root('anchor')[:3, 3] == pytest.approx(tree.to_root('winch_link')[:3, 3])
    # The IMU sees the body pitch: its x axis points theta_B above the horizontal.
    x_imu = tree.to_root('imu_link')[:3, 0]
    assert math.atan2(x_imu[2], x_imu[0]) == pytest.approx(theta_b, abs=1e-12)


def test_matches_the_core_forward_kinematics(joints):
    # rftgls_core.description poses the same URDF for the capacity computation: the tether
    # point and the mass centre it finds must be where the TF tree puts them.
    d = load_description(shipped_description('minirquad'))
    st = AnchorState(h=0.035, theta_b=math.radians(7.0), theta_l1=math.radians(-25.0),
                     theta_l2=math.radians(15.0))
    posed = d.pose({'h': st.h, 'theta_b': st.theta_b, 'theta_l1': st.theta_l1,
                     'theta_l2': st.theta_l2})
    names = ['leg_proximal_left', 'leg_proximal_right', 'leg_distal_left', 'leg_distal_right']
    tree = tree_from(static_transforms(joints),
                     [odom_to_base(st.h, st.theta_b),
                      *moving_transforms(joints, names, [st.theta_l1, st.theta_l1,
                                                         st.theta_l2, st.theta_l2])])
    assert tree.to_root('winch_link')[:3, 3] == pytest.approx(posed.ref, abs=1e-12)
    com_b = d.links['base_link'].com
    assert point(tree.to_root('base_link'), com_b) == pytest.approx(posed.com, abs=1e-12)
    # The legs' meshes (forward pull: the C-legs as in the URDF, no mirror): the core's posed
    # facets are the URDF leg facets moved by the TF tree's transforms.
    posed = d.pose({'h': st.h, 'theta_b': st.theta_b, 'theta_l1': st.theta_l1,
                     'theta_l2': st.theta_l2}, pull='forward')
    parts = []
    for link in ('left_proximal_leg', 'left_distal_leg', 'right_proximal_leg',
                 'right_distal_leg'):
        m = tree.to_root(link)
        parts.append(d.links[link].mesh.facets().centroids @ m[:3, :3].T + m[:3, 3])
    assert np.concatenate(parts) == pytest.approx(posed.facets.centroids, abs=1e-12)


def test_quaternion_round_trip_including_half_turns():
    rng = np.random.default_rng(3)
    qs = list(rng.normal(size=(200, 4))) + [np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0]),
                                             np.array([0, 0, 1.0, 1e-9])]
    for q in qs:
        r = quat_to_matrix(q)
        back = quat_to_matrix(matrix_to_quat(r))
        assert back == pytest.approx(r, abs=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)


def test_joint_state_names(joints):
    # The URDF's moving joints are the driver's JointState names (robot_state_publisher
    # matches by name).
    assert {j.name for j in joints if j.kind in MOVING} == set(LEG_JOINT_NAMES)
    # The winch rope is not in the URDF; a NaN position gives no transform, never a guess.
    ts = moving_transforms(joints, ['leg_proximal_left', 'winch_rope', 'leg_distal_left',
                                    'leg_proximal_right'], [0.1, 0.2, float('nan'), 0.3])
    assert [t.child for t in ts] == ['left_proximal_leg', 'right_proximal_leg']


def test_resolver_finds_what_does_not_resolve():
    ident = (0.0, 0.0, 0.0, 1.0)
    tree = TfTree([Transform('odom', 'base_link', (0, 0, 0), ident),
                   Transform('base_link', 'imu_link', (0, 0, 0), ident),
                   Transform('map', 'island', (0, 0, 0), ident)])
    assert tree.unresolved(['imu_link', 'base_link', 'odom']) == {}
    bad = tree.unresolved(['imu_link', 'base_link', 'island', 'anchor'])
    assert set(bad) == {'island', 'anchor'}
    assert "'map'" in bad['island'] and 'not in the tree' in bad['anchor']
    assert set(tree.unresolved(['imu_link'], root='map')) == {'imu_link'}
    tree.add([Transform('imu_link', 'odom', (0, 0, 0), ident)])
    with pytest.raises(ValueError, match='loop'):
        tree.root('base_link')


@pytest.mark.parametrize('text, match', [
    ('<robot', 'not XML'),
    ('<sdf/>', 'not a URDF'),
    ('<robot><joint name="j" type="fixed"><parent link="a"/></joint></robot>', 'lacks'),
    ('<robot><joint name="j" type="hinge"><parent link="a"/><child link="b"/></joint>'
     '</robot>', 'unknown type'),
    ('<robot><joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
     '<axis xyz="0 0 0"/></joint></robot>', 'zero axis'),
    ('<robot><joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
     '<origin xyz="0 nan 0"/></joint></robot>', 'finite'),
])
def test_bad_urdf_is_one_clear_error(text, match):
    with pytest.raises(UrdfError, match=match):
        parse_urdf_joints(text)
