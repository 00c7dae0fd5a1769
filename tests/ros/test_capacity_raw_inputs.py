"""Inputs judged before they are transformed, through a real capacity_node over DDS: garbage
that wrapping or normalising would turn into a plausible state never answers a value.

Each case first gets an `ok` answer from the good DH state (so the node works and the probe is
matched), then sends one bad message of one class and triggers an output with a tension
message. The output for that trigger carries no value (NaN capacity and margin), the status is
invalid_input, and /diagnostics names the reason code. Classes: raw leg angles beyond the
raw limit (which wrap to a plausible angle), a rolled IMU (the pitch formula ignores roll), an
IMU whose accelerometer disagrees with its orientation, non-unit quaternions (normalising
would hide them) and wrong frame_ids on the IMU and the tension. The rules and their tolerances
are in docs/design/capacity-inputs.md.
"""
from __future__ import annotations

import math

import pytest

rclpy = pytest.importorskip('rclpy')

from _capacity_common import DH, PHI, Probe  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from rftgls_core.types import pull_direction  # noqa: E402
from rftgls_ros.capacity.inputs import roll_rad  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402

DEG = math.pi / 180.0
# Generous timeouts: a lock-step test on a loaded machine may take a while between messages.
LIVE = {'map_file': '', 'live_method': 'twist-mesh', 'phi_rad': PHI, 'phi_topic': '/winch/phi',
        **{f'{n}_timeout_s': 5.0 for n in ('joint_states', 'pitch', 'tension', 'height', 'phi')}}


@pytest.fixture
def rig(ros_context):
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in LIVE.items()])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex, expect_phi=True)
    ex.add_node(node)
    ex.add_node(probe.node)
    probe.wait_matched()
    probe.state(DH)
    est = node.estimator
    assert probe.spin_until(lambda: 'pitch' in est._inputs and len(est._joints) == 4
                            and 'phi' in est._inputs and 'height' in est._inputs)
    # the first prediction of a fresh process may compile and build the twist mesh
    cap = probe.output_for(probe.tension(1.0).header.stamp, timeout=60.0)
    assert probe.wait_status('ok') and math.isfinite(cap.wrench.force.x)
    yield node, probe
    ex.shutdown()
    node.destroy_node()
    probe.node.destroy_node()


def along(w) -> float:
    d = pull_direction(PHI)
    return w.wrench.force.x * d[0] + w.wrench.force.z * d[1]


def imu_msg(probe, q, frame='imu_link', accel=None):
    from sensor_msgs.msg import Imu
    m = Imu()
    m.header.stamp = probe.next_stamp()
    m.header.frame_id = frame
    o = m.orientation
    o.x, o.y, o.z, o.w = q
    if accel is None:
        m.linear_acceleration_covariance[0] = -1.0   # REP-145: not provided
    else:
        a = m.linear_acceleration
        a.x, a.y, a.z = accel
    return m


def pitch_q(theta_b):
    beta = -theta_b          # REP-103 pitch, nose down positive
    return (0.0, math.sin(beta / 2), 0.0, math.cos(beta / 2))


def rolled_q(theta_b, roll):
    """Pitch theta_b (nose up), then roll about the body x axis: q_pitch * q_roll."""
    x1, y1, z1, w1 = pitch_q(theta_b)
    x2, w2 = math.sin(roll / 2), math.cos(roll / 2)
    return (w1 * x2 + x1 * w2, y1 * w2 + z1 * x2, z1 * w2 - y1 * x2, w1 * w2 - x1 * x2)


def no_value_for(probe, code, wait_for):
    """Trigger once `wait_for()` holds; the output for that trigger has no value, the status is
    invalid_input and /diagnostics names `code`."""
    assert probe.spin_until(wait_for), 'the bad message did not reach capacity_node'
    stamp = probe.tension(1.0).header.stamp
    cap = probe.output_for(stamp)
    margin = probe.output_for(stamp, 'margin')
    assert math.isnan(along(cap)) and math.isnan(along(margin))
    assert math.isnan(cap.wrench.force.y)                    # the "no value" mark
    assert probe.wait_status('invalid_input')
    assert probe.spin_until(lambda: probe.last_diag() is not None
                            and code in probe.last_diag().message), probe.last_diag()


@pytest.mark.parametrize('raw', [1e300, 6.28e6, 100.0, -7.0])
def test_a_raw_leg_angle_beyond_the_limit_answers_no_value(rig, raw):
    # Each wraps to some angle in [-pi, pi): without the raw check, a plausible state.
    node, probe = rig
    probe.joints(raw, DH.theta_l2)
    no_value_for(probe, 'outside_limits:joint_states',
                 lambda: node.estimator._joints['proximal_left'].value == raw
                 and node.estimator._joints['proximal_right'].value == raw)


def test_a_full_turn_within_the_raw_limit_still_answers(rig):
    node, probe = rig
    probe.joints(DH.theta_l1 + 2 * math.pi, DH.theta_l2)     # 5.58 rad: a [0, 2 pi) reading
    assert probe.spin_until(lambda: node.estimator._joints['proximal_left'].value
                            > math.pi)
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('ok') and math.isfinite(along(cap))


@pytest.mark.parametrize('roll_deg', [75.0, -30.0, 12.0])
def test_a_rolled_imu_answers_no_value(rig, roll_deg):
    # The pitch formula reads 5 deg whatever the roll: the roll itself must be judged.
    node, probe = rig
    q = rolled_q(DH.theta_b, roll_deg * DEG)
    assert roll_rad(q) == pytest.approx(roll_deg * DEG, abs=1e-9)
    probe.pub_imu.publish(imu_msg(probe, q))
    no_value_for(probe, 'implausible_roll:pitch', lambda: 'pitch' in node.estimator._malformed)


def test_an_imu_rolled_within_the_limit_still_answers(rig):
    node, probe = rig
    probe.pub_imu.publish(imu_msg(probe, rolled_q(DH.theta_b, 5 * DEG)))
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('ok') and math.isfinite(along(cap))


def test_an_accelerometer_against_the_orientation_answers_no_value(rig):
    # Orientation upright, but the specific force points down in the body frame (gravity
    # from above): the orientation cannot be trusted.
    node, probe = rig
    probe.pub_imu.publish(imu_msg(probe, pitch_q(DH.theta_b), accel=(0.0, 0.0, -9.81)))
    no_value_for(probe, 'implausible_gravity:pitch',
                 lambda: 'pitch' in node.estimator._malformed)


@pytest.mark.parametrize('scale', [10.0, 1e-5, 1e150, 1.01])
def test_a_quaternion_that_is_not_unit_is_refused_not_normalised(rig, scale):
    # Normalised, each would be exactly the DH pitch.
    node, probe = rig
    q = tuple(scale * c for c in pitch_q(DH.theta_b))
    probe.pub_imu.publish(imu_msg(probe, q))
    no_value_for(probe, 'malformed:pitch', lambda: 'pitch' in node.estimator._malformed)


@pytest.mark.parametrize('frame', ['base_link', '', 'winch_link'])
def test_an_imu_in_another_frame_answers_no_value(rig, frame):
    node, probe = rig
    probe.pub_imu.publish(imu_msg(probe, pitch_q(DH.theta_b), frame=frame))
    no_value_for(probe, 'wrong_frame:pitch', lambda: 'pitch' in node.estimator._malformed)


@pytest.mark.parametrize('frame', ['lab_world', '', 'imu_link'])
def test_a_tension_in_another_frame_answers_no_value(rig, frame):
    node, probe = rig
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.header.stamp = probe.next_stamp()
    m.header.frame_id = frame
    m.wrench.force.x = 1.0
    probe.pub_tension.publish(m)             # itself the trigger
    cap = probe.output_for(m.header.stamp)
    assert math.isnan(along(cap)) and math.isnan(cap.wrench.force.y)
    assert probe.wait_status('invalid_input')
    assert probe.spin_until(lambda: 'wrong_frame:tension' in probe.last_diag().message)
    # the next good tension answers again: nothing was lost
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('ok') and math.isfinite(along(cap))
