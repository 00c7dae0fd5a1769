"""Maps next to the support edge: the valued-corner and edge-margin rules.

Against the live reference (`direct`, the solver capacity_node falls back to) at random states
of each robot, both pulls, phi in -30..10 deg (a 40-state slice of the 300-state measurement
in maps/README.md): the map never answers where the reference has no value, never lies above
it by more than the error documented in maps/README.md, and answers more states than the
strict cell rule does. Single and batch queries agree on every answer and flag. The
edge-margin rule (schema-2 maps: a per-node support margin and its gradient) is checked on a
synthetic map whose margin is known in closed form, and the file schema on round trips and
tampered files.
"""
from __future__ import annotations

import numpy as np
import pytest
from tolerances import INTERPOLATION_ATOL, INTERPOLATION_RTOL

from rftgls_core.maps import CapacityMap, shipped_map_path
from rftgls_core.maps.accuracy import coverage_report
from rftgls_core.types import AnchorState

# maps/README.md, "Support edge": largest overestimate against the live solver over 5 x 300
# (prototype, +0.582 N) and 6 x 300 (MiniRQuad, +0.226 N) random states, rounded up to the
# documented bound.
DOCUMENTED_OVER_N = {'prototype': 0.59, 'minirquad': 0.23}
# ... and over all states, counting a map value where the live solver says the anchor holds
# nothing (unsupported: 0 N) in full: MiniRQuad's one such state (seed 4) is 0.512 N.
DOCUMENTED_OVER_ALL_N = {'prototype': 0.59, 'minirquad': 0.52}
# Coverage measured on this 40-state slice: 97.2 % (prototype), 97.1 % (MiniRQuad; 85.3 %
# with the valued-corner rule alone). The issue asks >= 95 % on 300 states (maps/README.md).
MIN_COVERAGE_PCT = {'prototype': 95.0, 'minirquad': 95.0}


@pytest.mark.parametrize('robot', ['prototype', 'minirquad'])
def test_edge_rule_answers_more_and_never_above_the_documented_error(robot):
    cmap = CapacityMap.load(shipped_map_path(robot))
    rep = coverage_report(cmap, n=40, seed=0)
    strict = coverage_report(CapacityMap.load(shipped_map_path(robot), edge_min_weight=2.0,
                                              edge_min_margin=None), n=40, seed=0)
    assert rep.map_only == 0, rep            # no value where the anchor cannot hold
    assert rep.over_N_worst <= DOCUMENTED_OVER_N[robot] + 1e-9, rep
    assert rep.over_all_N_worst == rep.over_N_worst    # no map-only value on this slice
    assert rep.coverage_pct >= MIN_COVERAGE_PCT[robot], rep
    assert rep.by_flag.get('edge_valued', 0) > 0 and 'edge_valued' not in strict.by_flag
    assert rep.map_answers > strict.map_answers
    if robot == 'minirquad':   # the edge cells need the margin rule to reach 95 %
        no_margin = coverage_report(CapacityMap.load(shipped_map_path(robot),
                                                     edge_min_margin=None), n=40, seed=0)
        assert no_margin.map_answers < rep.map_answers
        assert rep.by_flag.get('edge_margin', 0) > 0 and 'edge_margin' not in no_margin.by_flag
        assert no_margin.coverage_pct < MIN_COVERAGE_PCT[robot] <= rep.coverage_pct


def test_a_map_value_where_the_anchor_holds_nothing_counts_in_full_and_stays_documented():
    # maps/README.md: MiniRQuad seed 4 holds the one state (of 6 x 300) where the map answers
    # (edge_margin) and the live solver says unsupported; the anchor holds nothing there, so
    # the whole map value is the overestimate, and it is inside the documented all-states bound.
    rep = coverage_report(CapacityMap.load(shipped_map_path('minirquad')), n=300, seed=4)
    assert rep.map_only == 1
    assert 0.0 < rep.map_only_N_worst <= DOCUMENTED_OVER_ALL_N['minirquad']
    assert rep.over_N_worst <= DOCUMENTED_OVER_N['minirquad'] < rep.map_only_N_worst
    assert rep.over_all_N_worst == rep.map_only_N_worst
    assert rep.by_flag.get('edge_margin', 0) > 0


def single_and_batch_agree(cmap, n: int, seed: int, flag: str) -> list:
    """Query `n` random in-range states one by one and as a batch: same value, same `flag`.
    Returns the single answers that carry `flag`."""
    ax = cmap.axes
    rng = np.random.default_rng(seed)
    states = np.column_stack([rng.uniform(ax[name][0], ax[name][-1], n)
                              for name in ('h', 'theta_b', 'theta_l1', 'theta_l2')])
    phis = rng.uniform(cmap.phis[0], cmap.phis[-1], n)
    b = cmap.query_batch(states, phis, 'backward')
    flagged = []
    for k, (s, phi) in enumerate(zip(states, phis)):
        r = cmap.query(AnchorState(*s), float(phi), 'backward')
        assert (flag in r.flags) == bool(getattr(b, flag)[k])
        if r.capacity_N is None:
            assert np.isnan(b.capacity_N[k])
            continue
        # one query against the batched query: tests/tolerances.py
        assert b.capacity_N[k] == pytest.approx(r.capacity_N, rel=INTERPOLATION_RTOL,
                                                abs=INTERPOLATION_ATOL)
        if flag in r.flags:
            flagged.append(r)
    return flagged


def test_edge_rule_single_and_batch_agree_and_flag():
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    flagged = single_and_batch_agree(cmap, 400, 5, 'edge_valued')
    for r in flagged:
        assert 'blend of the valued corners' in r.detail
    assert len(flagged) >= 10
    with pytest.raises(ValueError, match='edge_min_weight'):
        CapacityMap(cmap.data, edge_min_weight=float('nan'))


# -- edge-margin rule (schema 2: per-node support margin and its gradient) ---------------------
def test_point_mesh_distance_against_a_cube():
    """Distance from a point to the surface of the cube [-1, 2]^3 (12 triangles), worked out
    by hand: inside at the origin 1 (faces x = -1, y = -1, z = -1); outside at (3, 0.5, 0.5)
    1 (face x = 2); outside past a corner at (3, 3, 3) sqrt(3); on a face 0."""
    from scipy.spatial import ConvexHull

    from rftgls_core.maps.edge import point_mesh_distance
    v = np.array([[x, y, z] for x in (-1.0, 2.0) for y in (-1.0, 2.0) for z in (-1.0, 2.0)])
    faces = ConvexHull(v).simplices
    assert point_mesh_distance(v, faces) == pytest.approx(1.0)
    assert point_mesh_distance(v, faces, np.array([3.0, 0.5, 0.5])) == pytest.approx(1.0)
    assert point_mesh_distance(v, faces, np.array([3.0, 3.0, 3.0])) == pytest.approx(3 ** 0.5)
    assert point_mesh_distance(v, faces, np.array([2.0, 0.3, 0.7])) == pytest.approx(0.0)



def test_point_mesh_distance_loop_is_the_numpy_expression_bitwise():
    """The compiled loop (surfaces/mesh_loops.py) does the numpy expression's operations in
    its order, so the distance is the same float (a minimum does not depend on the order it
    is taken in). On a lumpy closed sphere mesh from points inside, outside and on a vertex,
    and on a mesh with a degenerate (zero-area) triangle."""
    from rftgls_core.maps.edge import point_mesh_distance, point_mesh_distance_numpy
    from rftgls_core.surfaces.mesh_loops import HAVE_NUMBA
    from rftgls_core.surfaces.twist_sphere import TwistSphere
    if not HAVE_NUMBA:
        pytest.skip('numba not installed: point_mesh_distance is the numpy expression')
    rng = np.random.default_rng(3)
    sph = TwistSphere.build(500)
    v = sph.twists_scaled * (1.0 + 0.3 * rng.random((sph.n, 1))) * np.array([1.0, 0.4, 2.5])
    faces = np.vstack([sph.faces, [[0, 0, 1]]])
    points = [None, v[7], *rng.normal(scale=1.5, size=(20, 3))]
    for p in points:
        assert point_mesh_distance(v, faces, p) == point_mesh_distance_numpy(v, faces, p)


def _margin_map(tau=0.0):
    """A synthetic map (test_maps.synthetic) whose backward nodes at h >= 20 mm are
    unsupported, with the support margin m = 0.5 - 25 h (h in m): zero at h = 20 mm, exact
    gradient (-25, 0, 0, 0); so the edge lies ON the h = 20 mm nodes and the Taylor blend must
    reproduce m exactly."""
    import dataclasses

    from test_maps import OK, UNSUP, synthetic
    data = synthetic()
    g = data.grid
    status = data.status.copy()
    cap = data.capacity_N.copy()
    h = g.h
    far = h >= 0.02 - 1e-12
    status[1, far] = UNSUP
    cap[1, far] = np.nan
    ts = data.slip_twist_scaled.copy()
    ts[1, far] = np.nan
    margin = np.broadcast_to((0.5 - 25.0 * h)[None, :, None, None, None],
                             (len(g.pulls),) + g.state_shape).astype(np.float32).copy()
    # the forward pull is supported everywhere: a positive margin there
    margin[0] = np.abs(margin[0]) + 0.1
    margin[1, ~far] = np.maximum(margin[1, ~far], 0.0)
    grad = np.zeros(margin.shape + (4,), np.float32)
    grad[1, ..., 0] = -25.0
    assert status[0].max() == OK
    data = dataclasses.replace(data, capacity_N=cap, status=status, slip_twist_scaled=ts,
                               slip_twist=ts.copy(), support_margin=margin,
                               support_margin_grad=grad)
    return CapacityMap(data, edge_min_margin=tau), data


def test_edge_margin_rule_places_the_edge_inside_the_cell():
    from test_maps import state
    cmap, _ = _margin_map(tau=0.1)
    # cell h 10..20 mm: m = 0.5 - 25 h >= 0.1 for h <= 16 mm exactly; the valued corners'
    # share at h = 15 mm is 0.5 (< 0.9): only the margin rule can answer there
    yes = cmap.query(state(15, 5, 0, 30), -0.1, 'backward')
    assert yes.ok and yes.flags == ('edge_margin',), yes
    assert 'support margin 0.1250' in yes.detail
    # capacity: the valued corners' blend (the affine capacity at h = 10 mm) capped by s_F m
    s_f = cmap.data.attrs['scaling_force_N']
    assert yes.capacity_N == pytest.approx(min(cmap.query(state(10, 5, 0, 30), -0.1,
                                                          'backward').capacity_N,
                                               s_f * 0.125), rel=1e-5)
    no = cmap.query(state(17, 5, 0, 30), -0.1, 'backward')
    assert no.capacity_N is None and no.reason == 'cell_unsupported'
    # switched off: the strict cell rule
    off = CapacityMap(cmap.data, edge_min_margin=None)
    assert off.query(state(15, 5, 0, 30), -0.1, 'backward').capacity_N is None
    with pytest.raises(ValueError, match='edge_min_margin'):
        CapacityMap(cmap.data, edge_min_margin=float('inf'))


def test_edge_margin_single_and_batch_agree():
    cmap, _ = _margin_map(tau=0.05)
    assert len(single_and_batch_agree(cmap, 300, 3, 'edge_margin')) >= 10


def test_schema_2_roundtrip_hash_and_validation(tmp_path):
    import dataclasses

    import h5py

    from rftgls_core.maps import MapFileError, load_map, save_map
    _, data = _margin_map()
    path = save_map(tmp_path / 'm.h5', data)
    back = load_map(path)
    np.testing.assert_array_equal(back.support_margin, data.support_margin)
    np.testing.assert_array_equal(back.support_margin_grad, data.support_margin_grad)
    with h5py.File(path, 'r') as f:
        assert f.attrs['schema_version'] == 2
    # a version-1 map (no margin) still saves and loads as version 1, rule off
    v1 = dataclasses.replace(data, support_margin=None, support_margin_grad=None)
    p1 = save_map(tmp_path / 'v1.h5', v1)
    with h5py.File(p1, 'r') as f:
        assert f.attrs['schema_version'] == 1 and 'support_margin' not in f
    assert load_map(p1).support_margin is None
    # the content hash covers the margin and its gradient
    for name in ('support_margin', 'support_margin_grad'):
        bad = tmp_path / f'{name}.h5'
        bad.write_bytes(path.read_bytes())
        with h5py.File(bad, 'r+') as f:
            f[name][1, 0, 0, 0, 0] = f[name][1, 0, 0, 0, 0] + 0.01
        with pytest.raises(MapFileError, match='content hash'):
            load_map(bad)
    # a missing gradient, or a margin whose sign contradicts the statuses, is refused
    gone = tmp_path / 'gone.h5'
    gone.write_bytes(path.read_bytes())
    with h5py.File(gone, 'r+') as f:
        del f['support_margin_grad']
    with pytest.raises(MapFileError, match='support_margin_grad is missing'):
        load_map(gone)
    flipped = dataclasses.replace(data, support_margin=-np.abs(data.support_margin) - 0.1)
    with pytest.raises(MapFileError, match='support_margin does not match'):
        load_map(save_map(tmp_path / 'flip.h5', flipped))


def test_edge_cell_corners_marks_only_cells_that_straddle_the_support_edge():
    """On a 3 x 2 x 2 x 2 grid held only at h index 0: the cells between h index 0 and 1
    straddle the edge, so their corners (h index 0 and 1) need the gradient, h index 2 not;
    a pull held everywhere needs none."""
    from rftgls_core.maps.build import edge_cell_corners
    held = np.zeros((2, 3, 2, 2, 2), dtype=bool)
    held[0, 0] = True
    held[1] = True
    need = edge_cell_corners(held)
    assert need[0, :2].all() and not need[0, 2].any()
    assert not need[1].any()


def test_shipped_edge_corners_carry_the_dense_sphere_margin():
    # The edge-margin rule reads the margin only at the corners of cells that straddle the
    # support edge; there the build recomputes it on the dense sphere of the weight-held check
    # (the 1000-twist mesh gave margins up to 0.21 at states that cannot hold, the dense one at
    # most 0.027). Elsewhere the map's own sphere. Recomputed here at one node of each kind.
    from rftgls_core.maps.build import spec_from_map
    from rftgls_core.maps.edge import EDGE_MARGIN_TWISTS, node_support_margin
    from rftgls_core.surfaces.twist_sphere import TwistSphere

    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    data = cmap.data
    predictor = spec_from_map(data).predictor()
    p = 1                                               # backward pull
    grad_ok = np.isfinite(data.support_margin_grad[p, ..., 0])
    marg_ok = np.isfinite(data.support_margin[p])
    held = np.isfinite(data.capacity_N[p]).any(axis=-1)
    edge_node = tuple(np.argwhere(grad_ok & ~held)[0])    # an unsupported edge corner
    plain_node = tuple(np.argwhere(~grad_ok & marg_ok & held)[0])
    for node, n_twists, is_held in ((edge_node, EDGE_MARGIN_TWISTS, False),
                                    (plain_node, data.attrs['n_twists'], True)):
        k = int(np.ravel_multi_index(node, data.grid.state_shape))
        m = node_support_margin(predictor, TwistSphere.build(int(n_twists)), data.grid.state(k),
                                'backward', is_held)
        assert float(data.support_margin[p][node]) == pytest.approx(m, rel=1e-6, abs=1e-7)
