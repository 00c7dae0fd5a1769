"""Quasi-static slip trajectories: integrator order on an analytic field, convergence on the
real RFT model, and every stop reason."""
import math

import numpy as np
import pytest

from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.sim.trajectory import simulate_pull
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Status


class AnalyticField:
    """A smooth slip-twist field with a closed form: p translates at unit speed in a direction
    that turns with thetaB, and the body turns at a rate set by h. Capacity = 1 + h."""

    def predict(self, state, phi, pull):
        a = 0.3 + 2.0 * state.theta_b
        twist = (-math.cos(a), math.sin(a), -0.5 * (1.0 + 20.0 * state.h))  # wy; dthetaB = -wy
        return CapacityResult(phi=phi, status=Status.OK, method='analytic',
                              capacity_N=1.0 + state.h, slip_twist=twist)


def end_point(traj):
    p = traj.points[-1]
    return np.array([p.x_m, p.z_m, p.theta_b])


@pytest.mark.parametrize('integrator, order', [('euler', 1), ('heun', 2)])
def test_integrator_order_on_analytic_field(integrator, order):
    start = AnchorState(0.01, 0.0, 0.0, 0.0)
    never = lambda st: 1.0
    ref = end_point(simulate_pull(AnalyticField(), start, 0.0, 'forward', never, step=1e-5,
                                  integrator='heun', max_travel=0.02))
    errors = []
    for step in (2e-3, 1e-3, 5e-4):
        traj = simulate_pull(AnalyticField(), start, 0.0, 'forward', never, step=step,
                             integrator=integrator, max_travel=0.02)
        errors.append(np.linalg.norm(end_point(traj) - ref))
    ratios = [errors[i] / errors[i + 1] for i in range(2)]
    # halving the step divides the error by 2^order
    assert all(abs(math.log2(r) - order) < 0.3 for r in ratios), (errors, ratios)


@pytest.fixture(scope='module')
def prototype_model():
    return RobotPredictor(get_robot('prototype'), get_medium('glass_beads'), method='direct')


def test_real_trajectory_converges_with_step(prototype_model):
    start = AnchorState.from_degrees(0.02, 0.0, -40.0, 0.0)
    plate = lambda st: prototype_model.robot.pose(st, 'backward').plate_min_z
    ends = {}
    for step in (4e-3, 2e-3, 1e-3):
        traj = simulate_pull(prototype_model, start, 0.0, 'backward', plate, step=step,
                             integrator='heun', max_travel=0.012)
        assert traj.stop_reason.startswith('travel cap')
        ends[step] = end_point(traj)
    d1 = np.linalg.norm(ends[4e-3] - ends[1e-3])
    d2 = np.linalg.norm(ends[2e-3] - ends[1e-3])
    assert d2 < d1 and d2 < 2e-4  # 0.2 mm (and < 0.2 mrad) after 12 mm of slip


def test_stop_reasons(prototype_model):
    plate = lambda st: prototype_model.robot.pose(st, 'forward').plate_min_z
    # The weight is not carried here (see test_anchor): no balance at the first point.
    t = simulate_pull(prototype_model, AnchorState.from_degrees(0.03, 0, 40, 0), 0.0,
                      'forward', plate)
    assert len(t.points) == 1 and 'no quasi-static balance' in t.stop_reason
    # A plate already at the surface.
    t = simulate_pull(prototype_model, AnchorState.from_degrees(0.0, 0, -40, 0), 0.0,
                      'forward', plate)
    assert t.stop_reason == 'body plate reached the surface'
    with pytest.raises(ValueError):
        simulate_pull(prototype_model, AnchorState.from_degrees(0.02, 0, -40, 0), 0.0,
                      'forward', plate, integrator='rk4')
