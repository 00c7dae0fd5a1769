"""capacity_node and its estimator with a real (small) HDF5 map: ok, out_of_range (no value;
or the live solver when configured), unsupported, and the start-up errors of bad map files."""
from __future__ import annotations

import math

import pytest
from _capacity_common import DH, PHI, Probe

from rftgls_core.maps import CapacityMap
from rftgls_core.predictor.maps import FallbackPredictor, MapPredictor
from rftgls_core.types import AnchorState, Status
from rftgls_node_base.parameters import ConfigError
from rftgls_ros.capacity.estimator import CapacityEstimator, EstimatorConfig
from rftgls_ros.capacity.node_predictor import node_predictor

OUTSIDE = AnchorState(DH.h, math.radians(15.0), DH.theta_l1, DH.theta_l2)   # theta_b > 10 deg
HIGH = AnchorState(0.10, DH.theta_b, DH.theta_l1, DH.theta_l2)             # cell touches 200 mm
# maps/README.md, "Documented error": the largest map value where the live solver says the
# MiniRQuad anchor holds nothing (seed 4 of 6 x 300 random states: 0.512 N), rounded up.
DOCUMENTED_OVER_ALL_N = 0.52


def estimator_for(path, state, tension=1.0, predictor=None):
    est = CapacityEstimator(predictor or node_predictor(str(path), pull='backward'),
                            EstimatorConfig(pull='backward', phi_rad=PHI))
    est.update_joints(0.0, {'proximal_left': state.theta_l1, 'proximal_right': state.theta_l1,
                            'distal_left': state.theta_l2, 'distal_right': state.theta_l2})
    for name, v in (('pitch', state.theta_b), ('height', state.h), ('tension', tension),
                    ('phi', PHI)):
        est.update(name, 0.0, v)
    return est.estimate(0.0)


@pytest.mark.parametrize('state, status', [(DH, Status.OK), (HIGH, Status.UNSUPPORTED)])
def test_estimator_statuses_from_the_map(small_map, state, status):
    e = estimator_for(small_map, state)
    direct = CapacityMap.load(small_map).query(state, PHI, 'backward')
    assert e.status is status and direct.status is status
    if status is Status.OK:
        assert e.capacity_N == direct.capacity_N and e.slip_twist == direct.slip_twist
    elif status is Status.UNSUPPORTED:
        assert e.capacity_N == 0.0 and e.margin_N == -1.0 and e.slip_twist is None
    else:   # no value at all off the grid
        assert e.capacity_N is None and e.slip_twist is None


def test_off_grid_state_has_no_value(small_map):
    # The core map answers a state outside its grid with out_of_range (formerly a clamped
    # 'extrapolated' value); capacity_node publishes it with no value.
    direct = CapacityMap.load(small_map).query(OUTSIDE, PHI, 'backward')
    assert direct.status is Status.OUT_OF_RANGE
    e = estimator_for(small_map, OUTSIDE)
    assert e.status is Status.OUT_OF_RANGE and not e.has_value
    assert e.capacity_N is None and e.margin_N is None and e.slip_twist is None
    assert e.capacity_lower_N is None


def test_off_grid_state_answered_by_the_live_solver_when_configured(small_map, live_predictor):
    fb = node_predictor(str(small_map), pull='backward', out_of_range_live_method='twist-mesh')
    e = estimator_for(small_map, OUTSIDE, predictor=fb)
    live = live_predictor.predict(OUTSIDE, PHI, 'backward')
    assert live.status is Status.OK  # the reference has a value there
    assert e.status is Status.OK and e.capacity_N == pytest.approx(live.capacity_N, rel=1e-12)
    assert 'live_fallback' in e.reason_codes
    # inside the grid the map still answers
    inside = estimator_for(small_map, DH, predictor=fb)
    assert inside.capacity_N == CapacityMap.load(small_map).query(DH, PHI, 'backward').capacity_N


def test_edge_margin_answers_are_re_answered_by_the_live_solver():
    # maps/README.md: on MiniRQuad's random states of seed 4 (agreement_states, 300) the
    # shipped map answers one state through the edge-margin rule (0.512 N) where the live
    # `direct` says `unsupported`: the anchor holds nothing. With an edge checker (capacity_node
    # default: edge_live_method direct-warm) the live solver decides every edge-margin answer,
    # so that state is published as unsupported (0 N), never as 0.512 N, and edge answers where
    # the anchor holds take the live value.
    from rftgls_core.accuracy import agreement_states
    from rftgls_core.maps import shipped_map_path
    fb = node_predictor(str(shipped_map_path('minirquad')), edge_live_method='direct')
    mp, live = fb.primary, fb.edge
    edge = [(st, pull, phi) for st, pull, phi in agreement_states('minirquad', 300, 4)
            if 'edge_margin' in mp.predict(st, phi, pull).flags]
    assert len(edge) > 10
    held_nothing = 0
    for st, pull, phi in edge:
        m, r, ref = mp.predict(st, phi, pull), fb.predict(st, phi, pull), live.predict(
            st, phi, pull)
        assert m.status is Status.OK and m.capacity_N > 0.0
        assert r.status is ref.status and r.capacity_N == ref.capacity_N
        assert 'live_edge_check' in r.reason.split(';')
        if ref.status is Status.UNSUPPORTED:
            held_nothing += 1
            assert 0.5 < m.capacity_N <= DOCUMENTED_OVER_ALL_N and r.capacity_N is None
    assert held_nothing == 1
    # interior answers are the map's own
    st, pull, phi = next(j for j in agreement_states('minirquad', 300, 4)
                         if mp.predict(j[0], j[2], j[1]).status is Status.OK
                         and not mp.predict(j[0], j[2], j[1]).flags)
    assert fb.predict(st, phi, pull) == mp.predict(st, phi, pull)



def test_a_cell_the_support_edge_crosses_is_answered_by_the_live_solver():
    # SH's final legs (-40, 30 deg) at h 51 mm, pitch 2.4 deg, tether -4 deg: the shipped map's
    # cell spans h 45-55 mm and its 55 mm corners cannot hold the robot, without a support
    # margin to interpolate, so the map alone has no value (`unsupported`, flag
    # edge_unsupported). The live solver (the reference, no map) still finds the anchor holding
    # there; with an edge checker that answer is published, and where the live solver says
    # unsupported too (h 53 mm) so is the checked answer.
    from rftgls_core.maps import shipped_map_path
    fb = node_predictor(str(shipped_map_path('minirquad')), edge_live_method='direct')
    phi = math.radians(-4.0)
    for h_mm, holds in ((51.0, True), (53.0, False)):
        st = AnchorState.from_degrees(1e-3 * h_mm, 2.4, -40.0, 30.0)
        m, r, ref = (p.predict(st, phi, 'backward') for p in (fb.primary, fb, fb.edge))
        assert m.status is Status.UNSUPPORTED and 'edge_unsupported' in m.flags
        assert (ref.status is Status.OK) is holds
        assert r.status is ref.status and r.capacity_N == ref.capacity_N
        assert 'live_edge_check' in r.reason.split(';')
    # a cell whose valueless corners are not all unsupported keeps the conservative answer
    interior = fb.primary.predict(AnchorState.from_degrees(0.047, 2.4, -40.0, 30.0), phi,
                                  'backward')
    assert interior.status is Status.OK and 'edge_unsupported' not in interior.flags

def test_capacity_node_checks_edge_answers_by_default_and_can_be_told_not_to(small_map):
    from rftgls_ros.capacity.params import PARAMETERS
    assert PARAMETERS['edge_live_method'].default == 'direct-warm'
    p = node_predictor(str(small_map), edge_live_method='direct-warm')
    assert isinstance(p, FallbackPredictor) and p.fallback is None and p.edge is not None
    assert p.name.endswith('+live:direct-warm(edge check)')
    both = node_predictor(str(small_map), out_of_range_live_method='direct',
                          edge_live_method='direct')
    assert isinstance(both, FallbackPredictor) and both.edge is both.fallback   # one solver
    assert isinstance(node_predictor(str(small_map), edge_live_method=''),
                      MapPredictor)
    with pytest.raises(ConfigError, match='edge_live_method'):
        node_predictor(str(small_map), edge_live_method='bogus')


def test_bad_map_files(tmp_path, small_map):
    import h5py
    wrong = tmp_path / 'wrong_schema.h5'
    with h5py.File(wrong, 'w') as f:
        f['something'] = [1, 2, 3]
    with pytest.raises(ConfigError, match='bad map file'):
        node_predictor(str(wrong))
    text = tmp_path / 'not_hdf5.h5'
    text.write_text('hello\n')
    with pytest.raises(ConfigError, match='map file'):
        node_predictor(str(text))
    with pytest.raises(ConfigError, match='not found'):
        node_predictor(str(tmp_path / 'missing.h5'))
    with pytest.raises(ConfigError, match="not 'forward'"):
        node_predictor(str(small_map), pull='forward')
    with pytest.raises(ConfigError, match='robot'):
        node_predictor(str(small_map), robot='prototype')


def test_node_with_map_out_of_range_and_ok(ros_context, small_map):
    pytest.importorskip('rclpy')
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from test_capacity_node import f_along, send

    from rftgls_ros.capacity_node import CapacityNode
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter('map_file', value=str(small_map)), Parameter('phi_rad', value=PHI),
        Parameter('phi_topic', value='/winch/phi')])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex, expect_phi=True)
    ex.add_node(node)
    ex.add_node(probe.node)
    try:
        probe.wait_matched()
        cmap = CapacityMap.load(small_map)
        cap = send(probe, node, DH, 1.0)
        assert probe.wait_status('ok')
        assert f_along(cap) == pytest.approx(cmap.query(DH, PHI, 'backward').capacity_N)
        cap = send(probe, node, OUTSIDE, 1.0)
        assert probe.wait_status('out_of_range')
        assert math.isnan(f_along(cap))
        assert probe.wait_diag_level(DiagnosticStatus.ERROR)
        cap = send(probe, node, HIGH, 1.0)
        assert probe.wait_status('unsupported')
        assert (cap.wrench.force.x, cap.wrench.force.z) == (0.0, 0.0)
    finally:
        ex.shutdown()
        node.destroy_node()
        probe.node.destroy_node()
