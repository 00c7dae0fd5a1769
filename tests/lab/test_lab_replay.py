"""A synthetic pull-test bag replayed (recorded bytes, lock-step) into capacity_node."""
from __future__ import annotations

import math
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from rftgls_core.maps import CapacityMap  # noqa: E402
from rftgls_core.types import AnchorState, Status, pull_direction  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402
from rftgls_ros.lab.bag_layout import read_pull_test  # noqa: E402
from rftgls_ros.lab.replay import BagReplayer  # noqa: E402

MAP = 'maps/prototype_glass_beads.h5'


def test_replay_into_capacity_node(ros_context, synthetic_bags):
    # Legs on interior nodes: a map has no value off its grid (out_of_range), and the edge
    # poses' leg noise straddles the edge.
    bag = next(b for b in synthetic_bags if 'L1-020_L2+020' in b.name)
    test = read_pull_test(bag)
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter('map_file', value=MAP), Parameter('robot', value='prototype'),
        Parameter('medium', value='glass_beads'), Parameter('pull', value=test.meta.pull),
        Parameter('pitch_topic', value='/lab/theta_b'), Parameter('phi_topic', value='/winch/phi'),
        Parameter('publish_rate_hz', value=1.0),
        # recorded stamps are old; the bag's force is a world vector T d(phi)
        Parameter('freshness_source', value='receipt_time'),
        # Lock-step replay judged by receipt time: a worker descheduled for 0.25 s between the
        # last pitch and the last tension (another test on the 2 cores) made the last estimate
        # stale (NaN). Freshness is not what this test checks.
        *(Parameter(f'{name}_timeout_s', value=10.0)
          for name in ('joint_states', 'pitch', 'tension', 'height', 'phi')),
        Parameter('tension_component', value='tether'),
        Parameter('tension_frame_id', value='lab_world'),
        # the synthetic states reach just past the map's grid: the live solver answers there
        Parameter('out_of_range_live_method', value='twist-mesh')])
    player = rclpy.create_node('lab_replay', context=ros_context)
    probe = rclpy.create_node('lab_probe', context=ros_context)
    caps, meta = [], []
    probe.create_subscription(WrenchStamped, '/capacity_node/capacity', caps.append, 100)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    probe.create_subscription(String, '/lab/metadata', meta.append, latched)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (node, player, probe):
        ex.add_node(n)
    rep = BagReplayer(player, bag)
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and (
                player.count_subscribers('/winch/tension') < 1
                or probe.count_publishers('/capacity_node/capacity') < 1):
            ex.spin_once(timeout_sec=0.05)
        # lock-step: one recorded message, then let the node and the probe react
        n_tension = 0
        while (item := rep.step()) is not None:
            n_tension += item[0] == '/winch/tension'
            for _ in range(4 if item[0] == '/winch/tension' else 1):
                ex.spin_once(timeout_sec=0.002)
        end = time.monotonic() + 5
        while len(caps) < n_tension and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
    finally:
        rep.close()
        ex.shutdown()
        for n in (node, player, probe):
            n.destroy_node()
    assert meta and meta[0].data == test.meta.to_json()        # latched metadata arrived
    stamped = [c for c in caps if c.header.stamp.sec > 1_700_000_000]   # triggered by tension
    assert len(stamped) >= 0.9 * n_tension
    d = pull_direction(test.meta.phi_rad)
    values = [c.wrench.force.x * d[0] + c.wrench.force.z * d[1] for c in stamped]
    valid = [v for v in values if math.isfinite(v)]
    assert len(valid) > 0.5 * len(values)
    # the last output equals the map queried with the last recorded state
    last = test.pose[-1]
    state = AnchorState(float(last[1]), float(last[2]), *test.legs[-1])
    want = CapacityMap.load(MAP).query(state, test.meta.phi_rad, test.meta.pull)
    if want.status is Status.OK:  # inside the grid: the map answered
        assert values[-1] == pytest.approx(want.capacity_N, rel=0.02)


def test_replay_resolves_only_the_layouts_types(ros_context, tmp_path):
    """A bag names its message types as text; replay must never import a module a bag
    names. A bag that is not a lab pull test (no /lab/metadata) is refused before any
    publisher exists; nothing it names is resolved."""
    import sys

    from rosbags.rosbag2 import StoragePlugin, Writer

    from rftgls_ros.lab.bag_layout import BagError
    from rftgls_ros.lab.replay import message_class
    with pytest.raises(BagError):
        message_class('h4_evil_pkg/msg/Payload')
    assert 'h4_evil_pkg.msg' not in sys.modules and 'h4_evil_pkg' not in sys.modules
    assert message_class('std_msgs/msg/String') is String
    bag = tmp_path / 'hostile'
    with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection('/evil', 'h4_evil_pkg/msg/Payload', msgdef='int32 x',
                             rihs01='RIHS01_' + '0' * 64)
        w.write(c, 1, b'\x00\x01\x00\x00\x05\x00\x00\x00')
    node = rclpy.create_node('hostile_replay', context=ros_context)
    try:
        with pytest.raises(BagError, match='not a lab pull-test bag'):
            BagReplayer(node, bag)
        topics = {t for t, _ in node.get_publisher_names_and_types_by_node('hostile_replay', '/')}
        assert topics <= {'/parameter_events', '/rosout'}, topics    # rclpy's own only
    finally:
        node.destroy_node()
    assert 'h4_evil_pkg' not in sys.modules
