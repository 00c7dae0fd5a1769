"""Adaptive refinement adds nodes only on the axis intervals whose error needs them."""
import numpy as np

from rftgls_core.maps import CapacityMap, MapGrid, build_map
from rftgls_core.maps.refine import interval_errors, refined_grid


def tiny_map(grid):
    data = build_map('prototype', 'glass_beads', grid, n_twists=500, workers=1)
    return CapacityMap(data)


def test_refinement_targets_the_coarse_axis_and_reduces_its_error():
    # One coarse axis (thetaL1 over 60 deg) and one fine one (thetaL2 over 10 deg); every
    # node of this corner of the prototype grid holds the weight.
    grid = MapGrid.from_degrees([15, 25], [-5, 5], [-40, 20], [30, 40], [-10, 0],
                                pulls=('backward',))
    cmap = tiny_map(grid)
    errs = {e.axis: e for e in interval_errors(cmap, samples=6, seed=3)}
    coarse, fine = errs['theta_l1'], errs['theta_l2']
    assert coarse.compared >= 3 and fine.compared >= 3
    assert coarse.p95_pct > fine.p95_pct
    tol = 0.5 * (coarse.p95_pct + fine.p95_pct)
    new = refined_grid(grid, list(errs.values()), tol)
    assert np.allclose(np.degrees(new.theta_l1), [-40, -10, 20])     # midpoint added
    assert np.array_equal(new.theta_l2, grid.theta_l2)               # left alone
    refined = tiny_map(new)
    after = [e for e in interval_errors(refined, samples=6, seed=3) if e.axis == 'theta_l1']
    assert max(e.p95_pct for e in after) < coarse.p95_pct
