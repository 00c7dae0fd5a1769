"""capacity_node's estimator under each class of bad input (no ROS): none of them
answers `ok` or any value with a plausible number.

Every case starts from the same good, fully measured DH state (which answers `ok`; asserted
in test_capacity_estimator.py) and breaks one thing. Times are seconds on one clock; `NOW`
is the estimator's clock at the query, sample times are header stamps on the same clock.
"""
from __future__ import annotations

import math

import pytest
from _capacity_common import DH, PHI

from rftgls_core.types import AnchorState, Pull, Status
from rftgls_ros.capacity.estimator import CapacityEstimator, EstimatorConfig
from rftgls_ros.capacity.inputs import (
    axle_angle,
    frame_problem,
    gravity_problem,
    imu_problem,
    quat_xyzw_to_pitch,
    roll_rad,
    wrap_angle,
)

NOW = 1000.0
DEG = math.pi / 180.0


def legs(l1=DH.theta_l1, l2=DH.theta_l2, l1_right=None, l2_right=None):
    return {'proximal_left': l1, 'proximal_right': l1 if l1_right is None else l1_right,
            'distal_left': l2, 'distal_right': l2 if l2_right is None else l2_right}


def feed(est, t=NOW, joints=None, tension=1.0, height=DH.h, phi=PHI, times=None):
    """All inputs sampled at t, except those given other times in `times` (input -> t)."""
    times = times or {}
    est.update_joints(times.get('joint_states', t), joints or legs())
    est.update('pitch', times.get('pitch', t), DH.theta_b)
    if height is not None:
        est.update('height', times.get('height', t), height)
    if phi is not None:
        est.update('phi', times.get('phi', t), phi)
    est.update('tension', times.get('tension', t), tension)


@pytest.fixture
def est(live_predictor):
    return CapacityEstimator(live_predictor, EstimatorConfig(pull='backward', phi_rad=PHI,
                                                             height_m=DH.h))


def no_value(e):
    return (not e.has_value and e.capacity_N is None and e.margin_N is None
            and e.slip_twist is None and e.capacity_lower_N is None)


def test_the_good_case_answers_ok(est):
    feed(est)
    e = est.estimate(NOW)
    assert e.status is Status.OK and e.capacity_N > 0


# -- tension ------------------------------------------------------------------------------------
def test_negative_tension_is_invalid_not_folded(est):
    feed(est, tension=-5.0)
    e = est.estimate(NOW)
    assert e.status is Status.INVALID_INPUT and e.reason_codes == ('negative_tension:tension',)
    assert no_value(e) and e.tension_N == -5.0


def test_tension_inside_the_dead_band_counts_as_zero(est):
    feed(est, tension=-0.03)
    e = est.estimate(NOW)
    assert e.status is Status.OK and e.tension_N == 0.0 and e.margin_N == e.capacity_N


# -- legs ---------------------------------------------------------------------------------------
def test_left_and_right_legs_120_deg_apart_are_not_averaged(est):
    # their mean is exactly the DH angle, a perfectly plausible state
    feed(est, joints=legs(l1=DH.theta_l1 + 60 * DEG, l1_right=DH.theta_l1 - 60 * DEG))
    e = est.estimate(NOW)
    assert e.status is Status.INVALID_INPUT
    assert e.reason_codes == ('leg_disagreement:joint_states',) and no_value(e)
    assert e.leg_spread_rad[0] == pytest.approx(120 * DEG)


def test_minus_150_and_plus_150_deg_are_60_deg_apart(est):
    feed(est, joints=legs(l2=-150 * DEG, l2_right=150 * DEG))
    e = est.estimate(NOW)
    assert e.status is Status.INVALID_INPUT
    assert e.reason_codes == ('leg_disagreement:joint_states',) and no_value(e)
    assert e.leg_spread_rad[1] == pytest.approx(60 * DEG)


def test_angles_are_combined_on_the_circle():
    # the arithmetic mean of -150 and +150 deg is 0; on the circle they straddle 180 deg
    mean, spread = axle_angle(-179 * DEG, 179 * DEG)
    assert spread == pytest.approx(2 * DEG) and abs(mean) == pytest.approx(math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(-0.3) == -0.3


def test_a_full_turn_is_the_same_leg_angle(est, live_predictor):
    turned = legs(l1=DH.theta_l1 + 2 * math.pi, l2=DH.theta_l2 - 2 * math.pi)
    feed(est, joints=turned)
    e = est.estimate(NOW)
    core = live_predictor.predict(DH, PHI, Pull.BACKWARD)
    assert e.status is Status.OK and e.state.theta_l1 == pytest.approx(DH.theta_l1)
    assert e.capacity_N == pytest.approx(core.capacity_N, rel=1e-9)


# -- IMU ------------------------------------------------------------------------------------------
def _pitch_q(theta_b):
    beta = -theta_b  # REP-103 pitch, nose down positive
    return (0.0, math.sin(beta / 2), 0.0, math.cos(beta / 2))


def test_upright_imu_is_plausible():
    q = _pitch_q(10 * DEG)
    assert gravity_problem(q, None, 80 * DEG) is None
    # at rest the accelerometer reads +g along the world up, seen in the body frame
    up_body = (math.sin(-10 * DEG) * -1.0, 0.0, math.cos(10 * DEG))
    assert gravity_problem(q, tuple(9.81 * c for c in up_body), 80 * DEG) is None
    assert gravity_problem(q, (0.0, 0.0, 0.0), 80 * DEG) is None  # zeros: not provided


def test_upside_down_imu_is_implausible():
    x, y, z, w = _pitch_q(5 * DEG)
    flipped = (w, 0.0, -y, 0.0)  # the same pitch followed by a roll of 180 deg
    assert gravity_problem(flipped, None, 80 * DEG) is not None
    # orientation upright but the accelerometer sees gravity from above
    assert gravity_problem((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, -9.81), 80 * DEG) is not None


def test_upside_down_imu_gives_invalid_input(est):
    feed(est)
    est.mark_malformed('pitch', NOW, 'IMU: body up axis tilted 175 deg from the vertical',
                       code='implausible_gravity')
    e = est.estimate(NOW)
    assert e.status is Status.INVALID_INPUT
    assert e.reason_codes == ('implausible_gravity:pitch',) and no_value(e)


# -- time ---------------------------------------------------------------------------------------
@pytest.mark.parametrize('age_s', [10.0, 3600.0])
def test_old_stamps_are_stale_and_named(est, age_s):
    feed(est, times={'tension': NOW - age_s})
    e = est.estimate(NOW)
    assert e.status is Status.STALE and e.reason_codes == ('stale_input:tension',)
    assert e.stale == ('tension',) and no_value(e)


@pytest.mark.parametrize('ahead_s', [3600.0, 1.0])
def test_future_stamps_are_refused_and_named(est, ahead_s):
    feed(est, times={'joint_states': NOW + ahead_s})
    e = est.estimate(NOW)
    assert e.status is Status.INVALID_INPUT
    assert e.reason_codes == ('future_stamp:joint_states',) and no_value(e)


def test_a_clock_offset_inside_the_tolerance_is_accepted(est):
    feed(est, times={'tension': NOW + 0.04})  # tolerance 0.05 s
    assert est.estimate(NOW).status is Status.OK


@pytest.mark.parametrize('latency_s', [0.4, 2.0])
def test_link_latency_or_a_stall_makes_every_fast_input_stale(est, latency_s):
    # Every sample stamped when it was taken on the robot, arriving latency_s later: 400 ms
    # of link latency, or the backlog released after a 2 s host stall.
    feed(est, t=NOW - latency_s)
    e = est.estimate(NOW)
    assert e.status is Status.STALE and no_value(e)
    stale = {'joint_states', 'pitch', 'tension'}  # 0.25 s timeouts
    if latency_s > 1.0:
        stale |= {'height', 'phi'}                 # 1 s timeouts
    assert set(e.stale) == stale
    assert {c.split(':')[1] for c in e.reason_codes} == stale


# -- assumed inputs -------------------------------------------------------------------------------
def test_height_from_the_parameter_is_assumed_never_ok(est, live_predictor):
    feed(est, height=None)
    e = est.estimate(NOW)
    assert e.status is Status.ASSUMED and e.has_value
    assert e.reason_codes == ('assumed_input:height',) and e.assumed == ('height',)
    core = live_predictor.predict(DH, PHI, Pull.BACKWARD)
    assert e.capacity_N == pytest.approx(core.capacity_N, rel=1e-12)
    # The lower bound covers the assumed range (height_m +- 10 mm): no capacity of the
    # reference model anywhere in it is below the bound.
    for dh in (-0.01, -0.005, 0.0, 0.005, 0.01):
        st = AnchorState(DH.h + dh, DH.theta_b, DH.theta_l1, DH.theta_l2)
        ref = live_predictor.predict(st, PHI, Pull.BACKWARD)
        assert ref.status is Status.OK and e.capacity_lower_N <= ref.capacity_N + 1e-12
    assert 0.0 < e.capacity_lower_N < e.capacity_N


def test_assumed_phi_range_is_covered_too(est, live_predictor):
    feed(est, phi=None)
    e = est.estimate(NOW)
    assert e.status is Status.ASSUMED and e.reason_codes == ('assumed_input:phi',)
    for dphi in (-10 * DEG, 0.0, 10 * DEG):
        ref = live_predictor.predict(DH, PHI + dphi, Pull.BACKWARD)
        assert e.capacity_lower_N <= ref.capacity_N + 1e-12


def test_an_assumed_range_that_can_lose_the_anchor_bounds_at_zero(live_predictor):
    est = CapacityEstimator(live_predictor, EstimatorConfig(
        phi_rad=PHI, height_m=DH.h, assumed_height_range_m=0.2))  # up to 23 cm: in the air
    feed(est, height=None)
    e = est.estimate(NOW)
    assert e.status is Status.ASSUMED and e.capacity_lower_N == 0.0


# -- raw values, judged before they are transformed (docs/design/capacity-inputs.md) -----
@pytest.mark.parametrize('raw, ok', [(2 * math.pi, True), (-2 * math.pi, True),
                                     (2 * math.pi + 1e-9, False), (1e300, False),
                                     (6.28e6, False), (math.inf, False)])
def test_raw_leg_angles_are_judged_before_wrapping(est, raw, ok):
    feed(est, joints=legs(l1=raw, l1_right=raw))
    e = est.estimate(NOW)
    if ok:   # 2 pi wraps to 0: a plausible (if different) state, answered
        assert e.status is not Status.INVALID_INPUT
    else:
        assert e.status is Status.INVALID_INPUT and no_value(e)
        assert e.reason_codes in (('outside_limits:joint_states',),
                                  ('not_finite:joint_states',))


@pytest.mark.parametrize('scale, ok', [(1.0 + 0.9e-3, True), (1.0 - 0.9e-3, True),
                                       (1.0 + 1.1e-3, False), (1.0 - 1.1e-3, False),
                                       (10.0, False), (1e-5, False), (1e150, False)])
def test_quaternion_norm_tolerance(scale, ok):
    q = tuple(scale * c for c in _pitch_q(5 * DEG))
    problem = imu_problem(q, None, 80 * DEG, 10 * DEG)
    assert (problem is None) == ok, problem
    if not ok:
        assert problem[0] == 'malformed'


def _rolled(theta_b, roll):
    x1, y1, z1, w1 = _pitch_q(theta_b)
    x2, w2 = math.sin(roll / 2), math.cos(roll / 2)
    return (w1 * x2 + x1 * w2, y1 * w2 + z1 * x2, z1 * w2 - y1 * x2, w1 * w2 - x1 * x2)


@pytest.mark.parametrize('roll_deg, ok', [(0.0, True), (9.9, True), (-9.9, True),
                                          (10.1, False), (-10.1, False), (75.0, False)])
def test_roll_limit(roll_deg, ok):
    q = _rolled(5 * DEG, roll_deg * DEG)
    assert roll_rad(q) == pytest.approx(roll_deg * DEG, abs=1e-12)
    assert quat_xyzw_to_pitch(*q) == pytest.approx(5 * DEG, abs=1e-12)  # roll is invisible
    problem = imu_problem(q, None, 80 * DEG, 10 * DEG)
    assert (problem is None) == ok, problem
    if not ok:
        assert problem[0] == 'implausible_roll'


def test_frame_problem():
    assert frame_problem('imu_link', 'imu_link') is None
    assert 'expected' in frame_problem('', 'imu_link')
