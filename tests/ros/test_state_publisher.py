"""state_publisher in process with a probe, real DDS on loopback: /tf_static reaches a late
subscriber (transient local), /tf carries the leg joints of a JointState and odom -> base_link
from the IMU pitch and the height topic, a URDF given as text is used, a frame_prefix reaches
every frame, and a bad URDF is one clear error (exit 2 from `ros2 run`).

Reference values are worked out by hand from the URDF (see test_tf_tree.py)."""
from __future__ import annotations

import math
import subprocess
import time

import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('tf2_msgs')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from rftgls_conventions import pitch_to_quat_xyzw  # noqa: E402
from rftgls_ros.state_publisher import ConfigError, StatePublisher  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
TWO_LINKS = ('<robot name="t"><link name="base_link"/><link name="cam"/>'
             '<joint name="cam_joint" type="fixed"><parent link="base_link"/>'
             '<child link="cam"/><origin xyz="0.1 0.2 0.3" rpy="0 0 0"/></joint></robot>')


class Rig:
    def __init__(self, ctx, **params):
        self.node = StatePublisher(context=ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.probe = rclpy.create_node('tf_probe', context=ctx)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        self.ex.add_node(self.probe)
        self.static: list[TFMessage] = []
        self.tf: list[TFMessage] = []
        self.spin(0.3)      # the static message is out before anyone subscribes
        self.probe.create_subscription(TFMessage, '/tf_static', self.static.append, LATCHED)
        self.probe.create_subscription(TFMessage, '/tf', self.tf.append, 100)
        self.js = self.probe.create_publisher(JointState, 'joint_states', 10)
        self.imu = self.probe.create_publisher(Imu, 'imu/data', 10)
        self.height = self.probe.create_publisher(Float64, 'winch/height', 10)

    def spin(self, seconds, until=None):
        end = time.monotonic() + seconds
        while time.monotonic() < end and not (until and until()):
            self.ex.spin_once(timeout_sec=0.02)
        return until() if until else None

    def latest(self, child):
        for m in reversed(self.tf):
            for t in m.transforms:
                if t.child_frame_id == child:
                    return t
        return None

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()


@pytest.fixture
def rig(ros_context):
    made = []

    def make(**params):
        made.append(Rig(ros_context, **params))
        return made[-1]
    yield make
    for r in made:
        r.close()


def test_static_to_late_subscriber_and_dynamic_from_inputs(rig):
    r = rig()
    assert r.spin(5.0, lambda: r.static), 'no /tf_static for a late subscriber'
    st = {t.child_frame_id: t for t in r.static[-1].transforms}
    assert set(st) == {'imu_link', 'winch_link'}
    assert st['imu_link'].header.frame_id == 'base_link'
    assert st['imu_link'].transform.translation.x == pytest.approx(0.075)
    assert r.spin(5.0, lambda: r.js.get_subscription_count() and r.imu.get_subscription_count()
                  and r.height.get_subscription_count())
    r.spin(0.5)
    assert r.latest('base_link') is None       # no pitch yet: the body has no pose
    q = math.radians(90.0)
    r.height.publish(Float64(data=0.042))
    r.spin(0.3)
    m = JointState(name=['leg_proximal_left', 'winch_rope'], position=[q, 0.1])
    m.header.stamp.sec = 1234
    r.js.publish(m)
    imu = Imu()
    imu.header.stamp.sec = 1235
    imu.header.frame_id = 'imu_link'
    o = imu.orientation
    o.x, o.y, o.z, o.w = pitch_to_quat_xyzw(math.radians(10.0))
    r.imu.publish(imu)
    assert r.spin(5.0, lambda: r.latest('left_proximal_leg') and r.latest('base_link'))
    leg = r.latest('left_proximal_leg')
    assert leg.header.frame_id == 'base_link' and leg.header.stamp.sec == 1234
    s = math.sqrt(0.5)          # -90 deg about +y (hip axis -y, value +90 deg)
    rot = leg.transform.rotation
    assert (rot.x, rot.y, rot.z, rot.w) == pytest.approx((0, -s, 0, s), abs=1e-12)
    assert leg.transform.translation.y == pytest.approx(0.045)
    base = r.latest('base_link')
    assert base.header.frame_id == 'odom' and base.header.stamp.sec == 1235
    assert (base.transform.translation.x, base.transform.translation.z) == (0.0, 0.042)
    half = math.radians(-5.0)   # nose up 10 deg = -10 deg about +y
    rot = base.transform.rotation
    assert (rot.y, rot.w) == pytest.approx((math.sin(half), math.cos(half)), abs=1e-12)
    anchor = r.latest('anchor')
    assert anchor.transform.translation.z == 0.042 and anchor.transform.rotation.w == 1.0
    assert r.latest('winch_rope') is None
    # A height sent with its provenance (behavior_node's burrowed height) moves p as well.
    from rftgls_interfaces.msg import InputValue
    typed = r.probe.create_publisher(InputValue, 'winch/height_estimate', 10)
    assert r.spin(5.0, lambda: typed.get_subscription_count())
    typed.publish(InputValue(value=0.047, band=0.004, provenance=InputValue.ASSUMED))
    r.spin(0.3)
    imu.header.stamp.sec = 1236
    r.imu.publish(imu)
    assert r.spin(5.0, lambda: r.latest('anchor').header.stamp.sec == 1236)
    assert r.latest('anchor').transform.translation.z == 0.047


def _imu(q, frame='imu_link', sec=1):
    imu = Imu()
    imu.header.stamp.sec = sec
    imu.header.frame_id = frame
    o = imu.orientation
    o.x, o.y, o.z, o.w = q
    imu.linear_acceleration_covariance[0] = -1.0
    return imu


def _rolled(roll):
    return (math.sin(roll / 2), 0.0, 0.0, math.cos(roll / 2))


@pytest.mark.parametrize('what, imu', [
    ('rolled 75 deg', _imu(_rolled(math.radians(75.0)))),
    ('quaternion x10', _imu(tuple(10.0 * c for c in pitch_to_quat_xyzw(0.1)))),
    ('quaternion norm 1e150', _imu(tuple(1e150 * c for c in pitch_to_quat_xyzw(0.1)))),
    ('wrong frame', _imu(pitch_to_quat_xyzw(0.1), frame='base_link')),
])
def test_inputs_are_judged_before_they_are_drawn(rig, what, imu):
    # A good sample draws the body; then each bad one draws nothing (the good pose stands),
    # and a raw leg angle that would wrap to a plausible one draws no leg.
    r = rig()
    assert r.spin(5.0, lambda: r.imu.get_subscription_count() and r.js.get_subscription_count())
    r.imu.publish(_imu(pitch_to_quat_xyzw(0.1), sec=10))
    assert r.spin(5.0, lambda: r.latest('base_link') is not None)
    imu.header.stamp.sec = 20
    r.imu.publish(imu)
    r.js.publish(JointState(name=['leg_proximal_left'], position=[1e300]))
    r.js.publish(JointState(name=['leg_distal_left'], position=[0.5]))  # a good one, after
    assert r.spin(5.0, lambda: r.latest('left_distal_leg') is not None)
    r.spin(0.3)
    assert all(t.header.stamp.sec != 20 for m in r.tf for t in m.transforms), what
    assert r.latest('left_proximal_leg') is None


def test_urdf_text_and_frame_prefix(rig):
    r = rig(robot_description=TWO_LINKS, frame_prefix='robot1/')
    assert r.spin(5.0, lambda: r.static)
    (t,) = r.static[-1].transforms
    assert (t.header.frame_id, t.child_frame_id) == ('robot1/base_link', 'robot1/cam')
    assert (t.transform.translation.x, t.transform.translation.y,
            t.transform.translation.z) == pytest.approx((0.1, 0.2, 0.3))


@pytest.mark.parametrize('params, words', [
    ({'robot_description': '<robot><joint name="j" type="hinge"><parent link="a"/>'
      '<child link="b"/></joint></robot>'}, 'unknown type'),
    ({'robot': 'walker'}, 'no URDF in minirquad_description'),
])
def test_bad_description_is_a_config_error(ros_context, params, words):
    with pytest.raises(ConfigError, match=words):
        StatePublisher(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])


def test_ros2_run_bad_urdf_one_line_exit_2():
    proc = subprocess.run(['ros2', 'run', 'rftgls_ros', 'state_publisher', '--ros-args', '-p',
                           'robot_description:=<sdf/>'], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == ["state_publisher: error: robot_description is not a URDF (root element "
                     "'sdf')"], proc.stderr
