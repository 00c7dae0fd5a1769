"""A recorded sequence (rosbag2, written with rosbags) replayed lock-step into capacity_node:
every published capacity equals rftgls_core's RobotPredictor called directly on the same values."""
from __future__ import annotations

import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
rosbags = pytest.importorskip('rosbags')

from _capacity_common import JOINT_NAMES, PHI, Probe  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosbags.rosbag2 import Reader, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from rftgls_conventions import quat_xyzw_to_pitch  # noqa: E402
from rftgls_core.types import AnchorState, Pull, Status, pull_direction  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402

STEPS = 12
TOPICS = {'/joint_states': 'sensor_msgs/msg/JointState', '/imu/data': 'sensor_msgs/msg/Imu',
          '/winch/height': 'std_msgs/msg/Float64',
          '/winch/tension': 'geometry_msgs/msg/WrenchStamped'}


def record(path):
    """A burrowing-like sequence at 50 Hz: legs dig in, the body tips, tension ramps up."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Time = T['builtin_interfaces/msg/Time']
    Header = T['std_msgs/msg/Header']
    with Writer(path, version=8) as w:
        conns = {t: w.add_connection(t, ty, typestore=ts) for t, ty in TOPICS.items()}
        for k in range(STEPS):
            t_ns = 1_700_000_000_000_000_000 + k * 20_000_000
            stamp = Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9)
            hdr = Header(stamp=stamp, frame_id='base_link')
            l1 = math.radians(-40.0 + 1.5 * k)
            l2 = math.radians(30.0 - 1.0 * k)
            pos = np.array([l1 + 0.004, l1 - 0.004, l2 + 0.002, l2 - 0.002])
            js = T['sensor_msgs/msg/JointState'](header=hdr, name=list(JOINT_NAMES),
                                                 position=pos, velocity=np.array([]),
                                                 effort=np.array([]))
            beta = -math.radians(4.0 + 0.2 * k)  # REP-103 pitch (nose down positive)
            q = T['geometry_msgs/msg/Quaternion'](x=0.0, y=math.sin(beta / 2), z=0.0,
                                                  w=math.cos(beta / 2))
            v0 = T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
            imu = T['sensor_msgs/msg/Imu'](
                header=hdr, orientation=q, orientation_covariance=np.zeros(9),
                angular_velocity=v0, angular_velocity_covariance=np.zeros(9),
                linear_acceleration=v0, linear_acceleration_covariance=np.zeros(9))
            h = T['std_msgs/msg/Float64'](data=0.036 - 0.0005 * k)
            f = T['geometry_msgs/msg/Vector3'](x=0.5 + 0.6 * k, y=0.0, z=0.0)
            ws = T['geometry_msgs/msg/WrenchStamped'](
                header=hdr, wrench=T['geometry_msgs/msg/Wrench'](force=f, torque=v0))
            for topic, msg in (('/joint_states', js), ('/imu/data', imu), ('/winch/height', h),
                               ('/winch/tension', ws)):
                w.write(conns[topic], t_ns, ts.serialize_cdr(msg, TOPICS[topic]))


def test_lock_step_replay_matches_core(ros_context, tmp_path, live_predictor):
    bag = tmp_path / 'burrow_bag'
    record(bag)
    ts = get_typestore(Stores.ROS2_JAZZY)
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter('map_file', value=''), Parameter('live_method', value='twist-mesh'),
        Parameter('phi_rad', value=PHI),
        # the recorded IMU and force carry the body frame
        Parameter('imu_frame_id', value='base_link'),
        Parameter('tension_frame_id', value='base_link'),
        # recorded stamps are in the past: a replay is aged by receipt time
        Parameter('freshness_source', value='receipt_time'),
        # lock step: each message waits for the node to take the one before, so an input's
        # age measures this machine's load, not the data (a loaded CI runner took > 0.25 s)
        *(Parameter(f'{name}_timeout_s', value=60.0)
          for name in ('joint_states', 'pitch', 'tension', 'height'))])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex)
    ex.add_node(node)
    ex.add_node(probe.node)
    pubs = {'/joint_states': probe.pub_joints, '/imu/data': probe.pub_imu,
            '/winch/height': probe.pub_height, '/winch/tension': probe.pub_tension}
    est = node.estimator
    seen = {'/joint_states': lambda m: est._joints.get('distal_right') is not None
            and est._joints['distal_right'].value == m.position[3],
            '/imu/data': lambda m: 'pitch' in est._inputs and est._inputs['pitch'].value
            == quat_xyzw_to_pitch(m.orientation.x, m.orientation.y, m.orientation.z,
                                     m.orientation.w),
            '/winch/height': lambda m: 'height' in est._inputs
            and est._inputs['height'].value == m.data}
    compared = 0
    try:
        probe.wait_matched()
        current = {}
        with Reader(bag) as reader:
            for conn, _, raw in reader.messages():
                msg = ts.deserialize_cdr(raw, conn.msgtype)
                pubs[conn.topic].publish(bytes(raw))  # the recorded bytes, as `ros2 bag play`
                if conn.topic != '/winch/tension':
                    current[conn.topic] = msg
                    assert probe.spin_until(lambda c=conn, m=msg: seen[c.topic](m)), conn.topic
                    continue
                stamp = msg.header.stamp
                out = probe.output_for(_ros_time(stamp))
                js, imu, h = (current['/joint_states'], current['/imu/data'],
                              current['/winch/height'])
                state = AnchorState(
                    h.data, quat_xyzw_to_pitch(imu.orientation.x, imu.orientation.y,
                                                  imu.orientation.z, imu.orientation.w),
                    0.5 * (js.position[0] + js.position[1]),
                    0.5 * (js.position[2] + js.position[3]))
                core = live_predictor.predict(state, PHI, Pull.BACKWARD)
                d = pull_direction(PHI)
                got = out.wrench.force.x * d[0] + out.wrench.force.z * d[1]
                if core.status.has_value:
                    assert got == pytest.approx(core.capacity_N, rel=1e-9, abs=1e-12)
                    margin = probe.output_for(_ros_time(stamp), 'margin')
                    assert (margin.wrench.force.x * d[0] + margin.wrench.force.z * d[1]
                            == pytest.approx(core.capacity_N - msg.wrench.force.x, abs=1e-9))
                else:
                    assert core.status is Status.UNSUPPORTED and got == 0.0
                compared += 1
    finally:
        ex.shutdown()
        node.destroy_node()
        probe.node.destroy_node()
    assert compared == STEPS


def _ros_time(stamp):
    from builtin_interfaces.msg import Time
    return Time(sec=int(stamp.sec), nanosec=int(stamp.nanosec))
