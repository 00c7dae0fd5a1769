"""RobotPredictor on the real robots: statuses every caller relies on, and the acceptance of the
default method against the `direct` reference over a small harness of random states."""
import math

import pytest

from rftgls_core import accuracy as acc
from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.surfaces.registry import METHOD_NAMES
from rftgls_core.types import AnchorState, Status

METHODS = list(METHOD_NAMES)


def predictor(robot='prototype', method='twist-mesh', **kw):
    medium = 'glass_beads' if robot == 'prototype' else 'm90_sand'
    return RobotPredictor(get_robot(robot), get_medium(medium), method=method, **kw)


@pytest.mark.parametrize('method', METHODS)
def test_no_buried_leg_is_unsupported(method):
    r = predictor(method=method).predict(AnchorState.from_degrees(0.25, 0, 0, 0), 0.0, 'forward')
    assert r.status is Status.UNSUPPORTED and r.reason == 'no_buried_leg'
    assert r.capacity_N is None and r.slip_twist is None


@pytest.mark.parametrize('method', METHODS)
def test_weight_not_carried_is_unsupported(method):
    # Forward pull, proximal legs swung far from p (40 deg), distal legs vertical, p 30 mm up:
    # the legs are too shallow to carry the prototype's weight (the origin is outside the GLS;
    # the 10^5-twist brute-force reference agrees). At h = 20 mm the same pose holds a little
    # through the closure of the RFT map (0.19 N), see test_surfaces_closure.py.
    r = predictor(method=method).predict(AnchorState.from_degrees(0.03, 0, 40, 0), 0.0, 'forward')
    assert r.status is Status.UNSUPPORTED and r.capacity_N is None


@pytest.mark.parametrize('n_twists', [400, 1000])
def test_paper_forward_40_40_is_marginal(n_twists):
    # The paper finds no balance at (40, 40) deg for forward pulls. In our model the origin
    # sits on the limit surface there: unsupported at some sampling densities, a capacity
    # below 10 % of a good pose's at others; never a healthy-looking number (README).
    m = predictor(method='direct', n_twists=n_twists)
    weak = m.predict(AnchorState.from_degrees(0.02, 0, 40, 40), 0.0, 'forward')
    strong = m.predict(AnchorState.from_degrees(0.02, 0, -40, 0), 0.0, 'forward')
    assert (weak.status is Status.UNSUPPORTED and weak.capacity_N is None) or \
        weak.capacity_N < 0.1 * strong.capacity_N


@pytest.mark.parametrize('bad_state', [AnchorState(math.nan, 0, 0, 0),
                                       AnchorState(0.02, 0, math.inf, 0)])
def test_non_finite_state_is_invalid_input(bad_state):
    r = predictor().predict(bad_state, 0.0, 'forward')
    assert r.status is Status.INVALID_INPUT and r.capacity_N is None


@pytest.mark.parametrize('robot', ['prototype', 'minirquad'])
@pytest.mark.parametrize('bad_state', [
    AnchorState(-10.0, 0, 0, 0),                 # p 10 m under the sand: gave 5,391 N
    AnchorState(-0.06, 0, 0, 0),                 # deeper than the body is tall
    AnchorState(0.6, 0, 0, 0),                   # far above the sand: carried, not anchored
    AnchorState.from_degrees(0.02, 95, 0, 0),    # on its back
    AnchorState.from_degrees(0.02, 0, 270, 0),   # unwrapped leg angle
    AnchorState.from_degrees(0.02, 0, 0, -200)])
def test_state_outside_the_physical_range_has_no_value(robot, bad_state):
    r = predictor(robot, method='direct').predict(bad_state, 0.0, 'backward')
    assert r.status is Status.OUT_OF_RANGE and r.reason == 'outside_physical_range'
    assert r.capacity_N is None and r.slip_twist is None and not r.status.has_value


def test_status_list_has_no_extrapolated():
    # off-grid and off-range states have no value; nothing is clamped.
    assert 'extrapolated' not in {s.value for s in Status}
    assert {s for s in Status if s.has_value} == {Status.OK, Status.ASSUMED}


def test_non_finite_phi_and_too_few_twists():
    m = predictor()
    r = m.predict(AnchorState.from_degrees(0.02, 0, -40, 0), math.nan, 'forward')
    assert r.status is Status.INVALID_INPUT
    few = predictor(n_twists=5).predict(AnchorState.from_degrees(0.02, 0, -40, 0), 0.0, 'forward')
    assert few.status is Status.DEGENERATE and few.reason == 'too_few_twists'


def test_default_method_matches_direct_over_a_harness():
    """twist-mesh within 1 % and 2 deg of direct (same leg mesh), never
    more than 1 % above it, on random states of both robots, both pulls, phi = 0 and -20."""
    compared = mismatched = 0
    for robot in ('prototype', 'minirquad'):
        states = acc.sample_states(robot, 4, seed=7)
        tm = acc.run_config(robot, acc.Config('twist-mesh', 1000), states)
        ref = acc.run_config(robot, acc.Config('direct', 1000), states)
        s = acc.summarise(tm, ref)
        if s.compared:
            assert s.cap_err_pct_worst <= 1.0, s
            assert s.cap_over_pct_worst <= 1.0, s
            assert s.twist_err_deg_worst <= 2.0, s
        compared += s.compared
        mismatched += s.status_mismatch
    assert compared >= 20
    assert mismatched <= compared // 3  # unresolved jumps of the RFT map; reported, not hidden


def test_pareto_front():
    pts = [(1.0, 5.0), (2.0, 1.0), (3.0, 2.0), (0.5, 10.0), (4.0, 0.5)]
    assert acc.pareto_front(pts) == [3, 0, 1, 4]
