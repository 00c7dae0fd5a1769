"""CapacityEstimator without ROS: every status, leg averaging, caching, config checks."""
from __future__ import annotations

import math

import pytest
from _capacity_common import DH, IN_AIR, PHI

from rftgls_conventions import quat_xyzw_to_pitch
from rftgls_core.types import Pull, Status
from rftgls_node_base.parameters import ConfigError
from rftgls_ros.capacity.estimator import CapacityEstimator, EstimatorConfig
from rftgls_ros.capacity.node_predictor import node_predictor


def feed(est: CapacityEstimator, t: float, state=DH, tension=1.0, phi=PHI, spread=(0.0, 0.0)):
    est.update_joints(t, {'proximal_left': state.theta_l1 + spread[0] / 2,
                          'proximal_right': state.theta_l1 - spread[0] / 2,
                          'distal_left': state.theta_l2 + spread[1] / 2,
                          'distal_right': state.theta_l2 - spread[1] / 2})
    est.update('pitch', t, state.theta_b)
    est.update('height', t, state.h)
    est.update('phi', t, phi)
    est.update('tension', t, tension)


@pytest.fixture
def est(live_predictor):
    return CapacityEstimator(live_predictor, EstimatorConfig(pull='backward'))


def test_ok_matches_core_and_margin(est, live_predictor):
    feed(est, 10.0, tension=1.5)
    e = est.estimate(10.01)
    core = live_predictor.predict(DH, PHI, Pull.BACKWARD)
    assert e.status is Status.OK and e.has_value
    assert e.capacity_N == pytest.approx(core.capacity_N, rel=1e-12)
    assert e.margin_N == pytest.approx(core.capacity_N - 1.5)
    assert e.slip_twist == pytest.approx(core.slip_twist)
    assert not e.slipping and e.warnings == ()
    assert e.state == DH and e.phi_rad == PHI


def test_tension_above_capacity_predicts_slip(est):
    feed(est, 0.0, tension=50.0)
    e = est.estimate(0.0)
    assert e.status is Status.OK and e.slipping and e.margin_N < 0
    assert math.hypot(*e.slip_twist) == pytest.approx(1.0)


def test_new_tension_reuses_the_prediction(est):
    feed(est, 0.0, tension=1.0)
    est.estimate(0.0)
    n = est.predictions
    est.update('tension', 0.05, 2.0)
    e = est.estimate(0.05)
    assert est.predictions == n and e.tension_N == 2.0


@pytest.mark.parametrize('late', ['tension', 'pitch', 'height', 'phi', 'joint_states'])
def test_stale_input(est, late):
    feed(est, 0.0)
    # every input fresh at t = 2 except `late`, last seen at t = 0 (timeouts <= 1 s)
    if late != 'joint_states':
        est.update_joints(2.0, {k: v.value for k, v in est._joints.items()})
    for name in ('pitch', 'tension', 'height', 'phi'):
        if name != late:
            est.update(name, 2.0, est._inputs[name].value)
    e = est.estimate(2.0)
    assert e.status is Status.STALE and not e.has_value
    assert late in e.detail
    assert e.capacity_N is None and e.margin_N is None and e.slip_twist is None


def test_never_received_is_stale_and_parameter_inputs_are_assumed(live_predictor):
    est = CapacityEstimator(live_predictor, EstimatorConfig(height_m=DH.h, phi_rad=PHI))
    e = est.estimate(0.0)
    assert e.status is Status.STALE and 'no_data:tension' in e.reason_codes
    est.update_joints(0.0, {'proximal_left': DH.theta_l1, 'proximal_right': DH.theta_l1,
                            'distal_left': DH.theta_l2, 'distal_right': DH.theta_l2})
    est.update('pitch', 0.0, DH.theta_b)
    e = est.estimate(0.0)
    assert e.status is Status.STALE and e.stale == ('tension',)
    est.update('tension', 0.0, 1.0)
    e = est.estimate(0.0)
    # height and phi from parameters: a value, but never a plain ok
    assert e.status is Status.ASSUMED and e.has_value and e.state == DH and e.phi_rad == PHI
    assert set(e.reason_codes) == {'assumed_input:height', 'assumed_input:phi'}
    assert e.assumed == ('height', 'phi')
    est.update('height', 0.0, DH.h)
    assert est.estimate(0.0).reason_codes == ('assumed_input:phi',)
    est.update('phi', 0.0, PHI)
    assert est.estimate(0.0).status is Status.OK


@pytest.mark.parametrize('name, value, code', [
    ('tension', math.nan, 'not_finite:tension'),
    ('tension', -1.0, 'negative_tension:tension'),
    ('height', 0.5, 'outside_limits:height'),
    ('pitch', math.inf, 'not_finite:pitch'),
    ('phi', 2.0, 'outside_limits:phi'),
])
def test_invalid_scalar_input(est, name, value, code):
    feed(est, 0.0)
    est.update(name, 0.0, value)
    e = est.estimate(0.0)
    assert e.status is Status.INVALID_INPUT and e.reason_codes == (code,)
    assert e.capacity_N is None and e.margin_N is None and e.slip_twist is None


def test_invalid_joint_and_malformed(est):
    feed(est, 0.0)
    est.update_joints(0.0, {'distal_right': math.nan})
    e = est.estimate(0.0)
    assert e.status is Status.INVALID_INPUT and 'distal_right' in e.detail
    assert e.reason_codes == ('not_finite:joint_states',)
    feed(est, 0.1)
    assert est.estimate(0.1).status is Status.OK
    est.mark_malformed('pitch', 0.1, 'IMU publishes no orientation')
    e = est.estimate(0.1)
    assert e.status is Status.INVALID_INPUT and e.reason_codes == ('malformed:pitch',)
    est.update('pitch', 0.2, DH.theta_b)  # a good message clears it
    assert est.estimate(0.2).status is Status.OK


def test_small_leg_spread_is_combined(est):
    spread = (math.radians(4.0), math.radians(1.0))  # inside the 5 deg tolerance
    feed(est, 0.0, spread=spread)
    e = est.estimate(0.0)
    assert e.status is Status.OK and e.warnings == ()
    assert e.leg_spread_rad == pytest.approx(spread)
    assert e.state.theta_l1 == pytest.approx(DH.theta_l1)
    assert e.state.theta_l2 == pytest.approx(DH.theta_l2)


def test_unsupported_reports_zero_capacity(est):
    feed(est, 0.0, state=IN_AIR, tension=0.7)
    e = est.estimate(0.0)
    assert e.status is Status.UNSUPPORTED and not e.has_value
    assert e.capacity_N == 0.0 and e.margin_N == -0.7 and e.slipping
    assert e.slip_twist is None


@pytest.mark.parametrize('kwargs, words', [
    ({'timeouts_s': {'joint_states': -1.0, 'pitch': 1, 'tension': 1, 'height': 1, 'phi': 1}},
     'joint_states'),
    ({'pull': 'sideways'}, 'pull'),
    ({'height_m': 1.0}, 'height_m'),
    ({'leg_tolerance_rad': -0.1}, 'leg_tolerance_rad'),
    ({'clock_tolerance_s': -1.0}, 'clock_tolerance_s'),
    ({'assumed_height_range_m': math.nan}, 'assumed_height_range_m'),
])
def test_bad_config(live_predictor, kwargs, words):
    with pytest.raises(ConfigError, match=words):
        CapacityEstimator(live_predictor, EstimatorConfig(**kwargs))


def test_node_predictor_errors(tmp_path):
    with pytest.raises(ConfigError, match='live_method'):
        node_predictor('', live_method='bogus')
    with pytest.raises(ConfigError, match='not found|no CapacityMap'):
        node_predictor(str(tmp_path / 'missing.h5'))


def test_quat_xyzw_to_pitch_sign_and_yaw_invariance():
    beta = math.radians(12.0)  # REP-103 pitch: nose down
    q = (0.0, math.sin(beta / 2), 0.0, math.cos(beta / 2))
    assert quat_xyzw_to_pitch(*q) == pytest.approx(-beta)
    # add a yaw of 70 deg (q_yaw * q_pitch): elevation of the x axis is unchanged
    cy, sy = math.cos(math.radians(35)), math.sin(math.radians(35))
    w1, x1, y1, z1 = cy, 0.0, 0.0, sy
    w2, x2, y2, z2 = q[3], q[0], q[1], q[2]
    qq = (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
          w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)
    assert quat_xyzw_to_pitch(*qq) == pytest.approx(-beta)
    assert quat_xyzw_to_pitch(0, 0, 0, 2.0) == 0.0  # normalised first
    with pytest.raises(ValueError):
        quat_xyzw_to_pitch(0, 0, 0, 0)


# -- the output policy, without ROS (what capacity_node publishes) -----------------------------
def test_outputs_value_holding_and_slipping(est, live_predictor):
    feed(est, 0.0, tension=1.0)
    e = est.estimate(0.0)
    out = est.outputs(e)
    d = (-math.cos(PHI), math.sin(PHI))                 # tether direction, world (x, z)
    assert out.status == 'ok' and not out.publish_lower
    assert out.capacity_xz == pytest.approx((e.capacity_N * d[0], e.capacity_N * d[1]))
    assert out.margin_xz == pytest.approx((e.margin_N * d[0], e.margin_N * d[1]))
    assert out.capacity_y == 0.0
    assert out.slip_twist == (0.0, 0.0, 0.0)            # holds: no predicted motion
    est.update('tension', 0.01, 50.0)
    out = est.outputs(est.estimate(0.01))
    assert out.slip_twist == pytest.approx(live_predictor.predict(
        DH, PHI, Pull.BACKWARD).slip_twist)             # slipping: the raw twist


def test_outputs_without_value_are_nan_and_diagnostic_is_an_error(est):
    feed(est, 0.0, tension=-1.0)                        # negative tension: invalid_input
    e = est.estimate(0.0)
    out = est.outputs(e)
    assert out.status == 'invalid_input'
    assert all(math.isnan(v) for v in (*out.capacity_xz, out.capacity_y, *out.margin_xz,
                                        *out.slip_twist))
    d = est.diagnostic(e, 'capacity_node: anchor capacity', {'extra_ms': '1.0'})
    assert d.level == 2 and d.message.startswith('invalid_input: ')
    assert 'negative_tension:tension' in d.values['reason']
    assert d.values['capacity_N'] == 'nan' and d.values['extra_ms'] == '1.0'


def test_assumed_input_warns_and_publishes_the_lower_bound(live_predictor):
    est = CapacityEstimator(live_predictor, EstimatorConfig(pull='backward'))
    feed(est, 0.0, tension=1.0)
    est._inputs.pop('height')                           # never received: assumed height_m
    e = est.estimate(0.0)
    assert e.status is Status.ASSUMED
    assert est.outputs(e).publish_lower
    d = est.diagnostic(e, 'x')
    assert d.level == 1 and d.values['assumed_inputs'] == 'height'


def test_reconfigure_applies_from_the_next_estimate(est, live_predictor):
    import dataclasses
    feed(est, 0.0, tension=1.0)
    est._inputs.pop('phi')                              # phi from the parameter
    before = est.estimate(0.0).capacity_N
    est.reconfigure(dataclasses.replace(est.config, phi_rad=0.0))
    after = est.estimate(0.0).capacity_N
    assert after == pytest.approx(live_predictor.predict(DH, 0.0, Pull.BACKWARD)
                                  .capacity_N, rel=1e-12)
    assert after != before
    with pytest.raises(ConfigError):
        est.reconfigure(dataclasses.replace(est.config, pull='forward'))


# ------------------------------------------------------------------ input provenance
def _map_estimator(**cfg):
    from rftgls_core.maps import CapacityMap, shipped_map_path
    from rftgls_core.predictor.maps import MapPredictor
    path = shipped_map_path('minirquad')
    return CapacityEstimator(MapPredictor(CapacityMap.load(path), path),
                             EstimatorConfig(pull='backward', **cfg))


def _map_min(h_lo: float, h_hi: float) -> float:
    """Smallest capacity of the shipped map at five heights from h_lo to h_hi (ends
    included) at DH's angles: the map queried directly, not through the estimator."""
    import numpy as np

    from rftgls_core.maps import CapacityMap, shipped_map_path
    from rftgls_core.types import AnchorState
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    caps = [cmap.query(AnchorState(float(h), DH.theta_b, DH.theta_l1, DH.theta_l2), PHI,
                       'backward').capacity_N for h in np.linspace(h_lo, h_hi, 5)]
    return min(caps)


@pytest.mark.parametrize('provenance, status, word, assumed, modelled, code', [
    ('measured', Status.OK, 'ok', (), (), None),
    ('modelled', Status.OK, 'ok', (), ('height',), 'modelled_input:height'),
    ('assumed', Status.ASSUMED, 'assumed', ('height',), (), 'assumed_input:height'),
])
def test_every_estimate_says_which_inputs_were_not_measured(provenance, status, word, assumed,
                                                            modelled, code):
    """An estimate is ``ok`` on measured inputs and on a modelled height with its band (the
    provenance says ``height:modelled``, the lower bound covers the band); an assumed height
    makes it ``assumed``; the diagnostics name every input's provenance."""
    est = _map_estimator(lower_bound_level=0.0)
    feed(est, 0.0)
    est.update('height', 0.0, DH.h, provenance, 0.002)
    e = est.estimate(0.0)
    assert (e.status, e.word, e.assumed, e.modelled) == (status, word, assumed, modelled)
    assert e.has_value and est.outputs(e).status == word
    d = est.diagnostic(e, 'x')
    assert d.values['status'] == word and d.message.split(':')[0] == word
    assert d.values['provenance'] == (f'joint_states:measured,pitch:measured,tension:measured,'
                                      f'height:{provenance},phi:measured')
    if code is None:                           # measured: no range to cover, no bound asked
        assert e.reason == '' and e.capacity_lower_N is None
        assert not est.outputs(e).publish_lower
        assert d.level == 0
        return
    assert code in e.reason_codes
    # The lower bound covers the stated band: the smallest capacity over h +- 2 mm.
    assert e.capacity_lower_N == pytest.approx(_map_min(DH.h - 0.002, DH.h + 0.002), abs=1e-9)
    assert e.capacity_lower_N < e.capacity_N
    assert d.values[f'{provenance}_inputs'] == 'height'
    assert code in d.message
    assert d.level == 1                        # WARN: a value, on an input not measured


@pytest.mark.parametrize('provenance', ['assumed', 'modelled'])
def test_an_unstated_band_takes_the_configured_range_and_a_bad_one_is_refused(provenance):
    """Without a band the range is the node's assumption: the estimate is ``assumed`` (never
    ``ok``), a modelled value included, and its lower bound covers the configured range."""
    est = _map_estimator(lower_bound_level=0.0, assumed_height_range_m=0.003)
    feed(est, 0.0)
    est.update('height', 0.0, DH.h, provenance)            # band NaN: not stated
    e = est.estimate(0.0)
    assert (e.word, e.assumed, e.modelled) == ('assumed', ('height',), ())
    assert e.provenance()['height'] == 'assumed'
    assert e.capacity_lower_N == pytest.approx(_map_min(DH.h - 0.003, DH.h + 0.003), abs=1e-9)
    for band in (-0.001, math.inf):
        with pytest.raises(ValueError, match='band'):
            est.update('height', 0.0, DH.h, 'modelled', band)
    with pytest.raises(ValueError, match='tension is measured'):
        est.update('tension', 0.0, 1.0, 'assumed')


def test_a_malformed_value_keeps_its_provenance_until_a_good_one():
    est = _map_estimator()
    feed(est, 0.0)
    est.update('height', 0.0, DH.h, 'assumed', 0.002)
    est.mark_malformed('height', 0.1, 'provenance not stated')
    e = est.estimate(0.1)
    assert e.status is Status.INVALID_INPUT and e.assumed == ('height',)
    est.update('height', 0.2, DH.h, 'measured')
    assert est.estimate(0.2).status is Status.OK


def test_the_point_estimate_is_solved_at_the_rounded_angles_and_reports_the_measured_ones(
        live_predictor):
    """Resolution 0.05 deg: a tether angle creeping 0.01 deg per sample asks the predictor
    once per 0.05 deg; each estimate is the predictor's answer at phi and theta_B rounded to
    the nearest multiple of 0.05 deg, and reports the measured phi and state."""
    res = math.radians(0.05)
    est = CapacityEstimator(live_predictor, EstimatorConfig(
        pull='backward', phi_resolution_rad=res, theta_b_resolution_rad=res))
    pitch = DH.theta_b + math.radians(0.013)
    state = DH.__class__(DH.h, pitch, DH.theta_l1, DH.theta_l2)
    n0 = est.predictions
    seen = set()
    for k in range(25):                      # 0.25 deg of phi
        phi = PHI - math.radians(0.01) * k
        feed(est, 0.01 * k, state=state, phi=phi)
        e = est.estimate(0.01 * k)
        rounded = (round(phi / res) * res, round(pitch / res) * res)
        seen.add(rounded)
        core = live_predictor.predict(DH.__class__(DH.h, rounded[1], DH.theta_l1, DH.theta_l2),
                                      rounded[0], Pull.BACKWARD)
        assert e.status is Status.OK and e.capacity_N == core.capacity_N
        assert e.phi_rad == phi and e.state == state
    assert est.predictions - n0 == len(seen) <= 7


def test_a_negative_resolution_is_refused():
    with pytest.raises(ConfigError, match='phi_resolution_rad'):
        EstimatorConfig(phi_resolution_rad=-1e-4).check()
