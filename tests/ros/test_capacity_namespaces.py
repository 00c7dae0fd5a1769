"""Two robots on one ROS domain: two capacity_node processes
started as a user would (`ros2 run ... --ros-args -r __ns:=/robotN` with the shipped params
file), each fed different sensor inputs on its own relative topics, do not cross-talk: every
estimate a node publishes carries its own robot's inputs only, and its capacity is the one
`rftgls capacity --method map` (a separate process, the reference) gives for those inputs.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('rftgls_interfaces')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from rftgls_conventions import LEG_JOINT_NAMES, pitch_to_quat_xyzw  # noqa: E402
from rftgls_core.types import AnchorState  # noqa: E402
from rftgls_interfaces.msg import AnchorEstimate  # noqa: E402
from rftgls_node_base.dds_loopback import during_init  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
PHI = math.radians(-20.0)          # the params file's phi_rad (no phi topic: assumed)
ROBOTS = {
    'robot1': (AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0), 1.25),   # DH, 1.25 N
    'robot2': (AnchorState.from_degrees(0.045, 10.0, -20.0, 10.0), 2.5),
}


def cli_capacity(state: AnchorState) -> float:
    deg = [math.degrees(x) for x in (state.theta_b, state.theta_l1, state.theta_l2)]
    out = subprocess.run(
        [sys.executable, '-m', 'rftgls_core.cli.main', 'capacity', '--robot', 'minirquad',
         '--h', repr(state.h), '--theta-b', repr(deg[0]), '--theta-l1', repr(deg[1]),
         '--theta-l2', repr(deg[2]), '--phi', repr(math.degrees(PHI)), '--pull', 'backward',
         '--method', 'map', '--json'], capture_output=True, text=True, check=True, timeout=60,
        cwd=REPO)
    return float(json.loads(out.stdout)['capacity_N'])


def test_two_namespaced_capacity_nodes_do_not_cross_talk(spawn, ros_context, tmp_path):
    for ns in ROBOTS:
        log = open(tmp_path / f'{ns}.log', 'w')
        spawn(['ros2', 'run', 'rftgls_ros', 'capacity_node', '--ros-args', '-r',
               f'__ns:=/{ns}', '--params-file', 'ros2_ws/params/capacity_node.yaml',
               # a loaded machine must not turn the inputs stale between two publications
               *[x for n in ('joint_states', 'pitch', 'tension', 'height')
                 for x in ('-p', f'{n}_timeout_s:=30.0')]],
              stdout=log, stderr=log, cwd=REPO)
    node = rclpy.create_node('two_robots_probe', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    pubs, got = {}, {}
    for ns in ROBOTS:
        pubs[ns] = (node.create_publisher(JointState, f'/{ns}/joint_states', 10),
                    node.create_publisher(Imu, f'/{ns}/imu/data', 10),
                    node.create_publisher(Float64, f'/{ns}/winch/height', 10),
                    node.create_publisher(WrenchStamped, f'/{ns}/winch/tension', 10))
        got[ns] = []
        node.create_subscription(AnchorEstimate, f'/{ns}/capacity_node/estimate',
                                 got[ns].append, 50)

    def publish(ns):
        state, tension = ROBOTS[ns]
        js, imu, height, wrench = pubs[ns]
        stamp = node.get_clock().now().to_msg()
        m = JointState(name=list(LEG_JOINT_NAMES),
                       position=[state.theta_l1, state.theta_l1, state.theta_l2,
                                 state.theta_l2])
        m.header.stamp = stamp
        js.publish(m)
        i = Imu()
        i.header.stamp, i.header.frame_id = stamp, 'imu_link'
        o = i.orientation
        o.x, o.y, o.z, o.w = pitch_to_quat_xyzw(state.theta_b)
        i.linear_acceleration_covariance[0] = -1.0       # REP-145: not provided
        imu.publish(i)
        height.publish(Float64(data=state.h))
        w = WrenchStamped()
        w.header.stamp, w.header.frame_id = stamp, 'winch_link'
        w.wrench.force.x = tension
        wrench.publish(w)

    def own(ns, e) -> bool:
        state, tension = ROBOTS[ns]
        return e.has_value and e.tension_n == tension and e.h_m == state.h and \
            e.theta_l1_rad == pytest.approx(state.theta_l1, abs=1e-12) and \
            e.theta_b_rad == pytest.approx(state.theta_b, abs=1e-9)

    end = time.monotonic() + 60
    while time.monotonic() < end and not all(any(own(ns, e) for e in got[ns])
                                             for ns in ROBOTS):
        if all(p.get_subscription_count() > 0 for ns in ROBOTS for p in pubs[ns]):
            for ns in ROBOTS:
                publish(ns)
        stop = time.monotonic() + 0.2
        while time.monotonic() < stop:
            ex.spin_once(timeout_sec=0.02)
    logs = '\n'.join((tmp_path / f'{ns}.log').read_text() for ns in ROBOTS)
    for ns in ROBOTS:
        assert any(own(ns, e) for e in got[ns]), f'{ns}: no estimate of its inputs\n{logs}'

    for ns, (state, tension) in ROBOTS.items():
        other_state, other_tension = next(v for k, v in ROBOTS.items() if k != ns)
        # Nothing of the other robot ever shows up in this robot's estimates.
        for e in got[ns]:
            assert e.tension_n != other_tension, (ns, e)
            # (before its first height message a node uses the assumed height_m of the params
            # file, which may equal the other robot's: that is not cross-talk)
            assert 'height' in e.assumed_inputs or not e.h_m == other_state.h, (ns, e)
            assert not e.theta_l2_rad == pytest.approx(other_state.theta_l2, abs=1e-9)
        mine = [e for e in got[ns] if own(ns, e)]
        ref = cli_capacity(state)
        assert mine[-1].capacity_n == pytest.approx(ref, rel=0, abs=1e-9), ns
        assert mine[-1].margin_n == pytest.approx(ref - tension, abs=1e-9), ns
    assert cli_capacity(ROBOTS['robot1'][0]) != pytest.approx(
        cli_capacity(ROBOTS['robot2'][0]), rel=1e-3)      # the two inputs are distinguishable
    ex.shutdown()
    node.destroy_node()


def test_shipped_params_file_applies_under_a_namespace():
    """The shipped params file keys its section '/**/capacity_node' (rcl's wildcard): a bare
    'capacity_node:' would match /capacity_node only and leave a namespaced node on defaults."""
    import os

    import yaml
    from rclpy.node import Node
    path = REPO / 'ros2_ws' / 'params' / 'capacity_node.yaml'
    want = yaml.safe_load(path.read_text())['/**/capacity_node']['ros__parameters']['height_m']
    ctx = rclpy.Context()
    with during_init():
        rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']),
                   args=['--ros-args', '--params-file', str(path)])
    try:
        got = {}
        for ns in ('', 'robot1'):
            n = Node('capacity_node', namespace=ns, context=ctx)
            got[ns] = n.declare_parameter('height_m', -1.0).value
            n.destroy_node()
        assert got[''] == want          # the file is read at all
        assert got['robot1'] == want, got
    finally:
        rclpy.try_shutdown(context=ctx)
