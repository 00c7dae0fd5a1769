"""Capacity maps without RFT: grid, file schema and validation, interpolation and statuses.

Synthetic maps: capacity and twists are affine functions of (state, phi), which multilinear
interpolation must reproduce exactly (to float32 storage rounding).
"""
import math

import h5py
import numpy as np
import pytest
from tolerances import INTERPOLATION_ATOL, INTERPOLATION_RTOL

from rftgls_core.maps import CapacityMap, MapData, MapFileError, MapGrid, load_map, save_map
from rftgls_core.maps.grid import default_grid, parse_range
from rftgls_core.maps.hdf5 import STATUS_NAMES
from rftgls_core.types import AnchorState, Pull, Status

OK, UNSUP, DEGEN = (STATUS_NAMES.index(s.value) for s in
                    (Status.OK, Status.UNSUPPORTED, Status.DEGENERATE))
COEF = np.array([40.0, 2.0, 1.5, -1.0, 3.0])    # capacity = 10 + COEF . (h, tb, l1, l2, phi)


def small_grid():
    return MapGrid.from_degrees([5, 10, 20], [-10, 0, 10], [-20, 20], [0, 20, 40], [-20, -10, 0])


def capacity_fn(h, tb, l1, l2, phi):
    return 10.0 + COEF[0] * h + COEF[1] * tb + COEF[2] * l1 + COEF[3] * l2 + COEF[4] * phi


def synthetic(grid=None, twist=(0.6, 0.0, 0.8)):
    g = grid or small_grid()
    mesh = np.meshgrid(*g.axes, g.phi, indexing='ij')
    cap = np.broadcast_to(capacity_fn(*mesh), g.shape).astype(np.float32)
    ts = np.broadcast_to(np.asarray(twist, np.float32), g.shape + (3,)).copy()
    attrs = {'robot': 'prototype', 'medium': 'glass_beads', 'method': 'twist-mesh',
             'rft_model': 'agarwal', 'n_twists': 100, 'scaling_force_N': 1.1772,
             'scaling_length_m': 0.1, 'package_version': 'test', 'build_command': 'synthetic',
             'provenance_json': '{"medium": {"name": "glass_beads"}}',
             'build_time_utc': '2026-01-01T00:00:00+00:00'}
    return MapData(grid=g, capacity_N=cap.copy(), slip_twist_scaled=ts, slip_twist=ts.copy(),
                   status=np.full(g.shape, OK, np.uint8), reason=np.zeros(g.shape, np.uint8),
                   reason_names=('', 'origin_outside'), attrs=attrs)


def state(h_mm, tb, l1, l2):
    return AnchorState.from_degrees(h_mm * 1e-3, tb, l1, l2)


# -- grid -------------------------------------------------------------------------------------
def test_parse_range_and_default_grids():
    assert parse_range('5:5:30').tolist() == [5, 10, 15, 20, 25, 30]
    assert parse_range('-40:20:40').tolist() == [-40, -20, 0, 20, 40]
    assert parse_range('1,2.5,4').tolist() == [1, 2.5, 4]
    with pytest.raises(ValueError):
        parse_range('1:0:4')
    proto = default_grid('prototype')
    assert proto.n_states == 750 and proto.pulls == ('forward', 'backward')
    phi_deg = np.degrees(proto.phi)
    assert np.any(np.isclose(phi_deg, 0)) and np.any(np.isclose(phi_deg, -20))
    mini = default_grid('minirquad')
    # Table II final poses (thetaB, h) and legs lie inside the MiniRQuad grid.
    for tb, h_mm, l1, l2 in ((5.0, 34, -40, 30), (8.9, 36, -40, 0), (2.4, 47, -40, 30)):
        x = (h_mm * 1e-3, math.radians(tb), math.radians(l1), math.radians(l2))
        assert all(a[0] <= v <= a[-1] for a, v in zip(mini.axes, x))
    with pytest.raises(ValueError):
        MapGrid.from_degrees([5, 5], [0, 1], [0, 1], [0, 1], [0, 1])


# -- file schema --------------------------------------------------------------------------------
def test_roundtrip(tmp_path):
    data = synthetic()
    back = load_map(save_map(tmp_path / 'm.h5', data))
    assert back.grid == data.grid
    for name in ('capacity_N', 'slip_twist_scaled', 'slip_twist', 'status', 'reason'):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))
    assert back.attrs == data.attrs and back.reason_names == data.reason_names
    with h5py.File(tmp_path / 'm.h5') as f:
        assert f['axes/h'].attrs['units'] == 'm'
        assert list(f['axes/theta_b'].attrs['human_values']) == [-10, 0, 10]
        assert list(f['status'].attrs['status_names']) == list(STATUS_NAMES)
    cmap = CapacityMap.load(tmp_path / 'm.h5')
    assert cmap.robot_name == 'prototype' and cmap.medium_name == 'glass_beads'
    assert cmap.pulls == ('forward', 'backward') and len(cmap.phis) == 3
    assert set(cmap.axes) == {'h', 'theta_b', 'theta_l1', 'theta_l2'}
    assert cmap.provenance['medium']['name'] == 'glass_beads'


def _corrupt(path, how):
    if how == 'truncated':
        raw = path.read_bytes()
        path.write_bytes(raw[:len(raw) // 2])
    elif how == 'garbage':
        path.write_bytes(b'not an hdf5 file at all' * 10)
    else:
        with h5py.File(path, 'r+') as f:
            if how == 'version':
                f.attrs['schema_version'] = 99
            elif how == 'schema':
                f.attrs['schema'] = 'something.else'
            elif how == 'missing':
                del f['slip_twist_scaled']
            elif how == 'shape':
                del f['capacity_N']
                f['capacity_N'] = np.zeros((2, 2), np.float32)
            elif how == 'dtype':
                del f['status']
                f['status'] = np.zeros(f['reason'].shape, np.float32)
            elif how == 'axis':
                del f['axes/h']
                f['axes/h'] = np.array([0.005, 0.02, 0.01])
            elif how == 'nan_axis':
                f['axes/phi'][1] = np.nan
            elif how == 'code':
                f['status'][0, 0, 0, 0, 0, 0] = 200
            elif how == 'attr':
                del f.attrs['scaling_length_m']
            elif how == 'negative':
                f['capacity_N'][0, 0, 0, 0, 0, 0] = -1.0


@pytest.mark.parametrize('how', ['truncated', 'garbage', 'version', 'schema', 'missing', 'shape',
                                 'dtype', 'axis', 'nan_axis', 'code', 'attr', 'negative'])
def test_rejects_bad_files(tmp_path, how):
    path = save_map(tmp_path / 'm.h5', synthetic())
    _corrupt(path, how)
    with pytest.raises(MapFileError) as err:
        CapacityMap.load(path)
    msg = str(err.value)
    assert '\n' not in msg and str(path) in msg
    assert isinstance(err.value, ValueError)


def test_missing_file(tmp_path):
    with pytest.raises(MapFileError, match='no such map file'):
        load_map(tmp_path / 'nope.h5')


# -- interpolation ------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def cmap():
    return CapacityMap(synthetic())


def test_nodes_and_affine_reproduction(cmap):
    g = cmap.grid
    r = cmap.query(AnchorState(g.h[1], g.theta_b[2], g.theta_l1[0], g.theta_l2[1]), g.phi[1],
                   'backward')
    assert r.status is Status.OK and r.method == 'map'
    want = capacity_fn(g.h[1], g.theta_b[2], g.theta_l1[0], g.theta_l2[1], g.phi[1])
    assert r.capacity_N == pytest.approx(want, rel=1e-6)
    rng = np.random.default_rng(1)
    lo = np.array([a[0] for a in g.axes] + [g.phi[0]])
    hi = np.array([a[-1] for a in g.axes] + [g.phi[-1]])
    for x in lo + (hi - lo) * rng.random((50, 5)):
        r = cmap.query(AnchorState(*x[:4]), x[4], Pull.FORWARD)
        assert r.status is Status.OK
        assert r.capacity_N == pytest.approx(capacity_fn(*x), rel=1e-5)
        assert r.slip_twist_scaled == pytest.approx((0.6, 0.0, 0.8), abs=1e-6)
        # raw twist = S^-1 ts normalised: wy carries 1/L_c
        raw = np.array([0.6, 0.0, 0.8 / 0.1])
        assert r.slip_twist == pytest.approx(tuple(raw / np.linalg.norm(raw)), abs=1e-6)
        assert 'twist_confidence=1.000' in r.detail


def test_out_of_grid_has_no_value(cmap):
    inside = cmap.query(state(20, 0, 20, 40), 0.0, 'backward')
    out = cmap.query(state(35, 0, 30, 40), math.radians(10), 'backward')
    assert inside.status is Status.OK
    # Outside the grid the map knows nothing: no clamped edge value.
    assert out.status is Status.OUT_OF_RANGE and out.reason == 'out_of_grid'
    assert out.capacity_N is None and out.slip_twist is None and not out.status.has_value
    assert 'h 35 mm above grid' in out.detail and 'theta_l1' in out.detail and 'phi' in out.detail
    below = cmap.query(state(1, -30, 0, 20), -1.0, 'backward')
    assert below.status is Status.OUT_OF_RANGE and 'below grid' in below.detail
    assert below.capacity_N is None
    # Within the snap tolerance of the edge node is still on the grid.
    edge = cmap.query(state(20 * (1 + 1e-9), 0, 20, 40), 0.0, 'backward')
    assert edge.status is Status.OK
    batch = cmap.query_batch([[0.035, 0.0, math.radians(30), math.radians(40)],
                              [0.020, 0.0, math.radians(20), math.radians(40)]],
                             [math.radians(10), 0.0], 'backward')
    assert batch.statuses() == [Status.OUT_OF_RANGE, Status.OK]
    assert math.isnan(batch.capacity_N[0]) and batch.capacity_N[1] == pytest.approx(
        inside.capacity_N, rel=INTERPOLATION_RTOL)             # single against batched query


def test_invalid_inputs(cmap):
    for r in (cmap.query(state(float('nan'), 0, 0, 0), 0.0, 'backward'),
              cmap.query(state(10, 0, 0, 0), float('inf'), 'backward'),
              cmap.query(state(10, 0, 0, 0), 0.0, 'sideways'),
              cmap.query((0.01, 0, 0, 0), 0.0, 'backward')):
        assert r.status is Status.INVALID_INPUT and r.capacity_N is None
    one_pull = synthetic()
    one_pull.grid = MapGrid(*one_pull.grid.axes, one_pull.grid.phi, pulls=('backward',))
    for name in ('capacity_N', 'status', 'reason', 'slip_twist_scaled', 'slip_twist'):
        setattr(one_pull, name, getattr(one_pull, name)[1:])
    r = CapacityMap(one_pull).query(state(10, 0, 0, 0), 0.0, 'forward')
    assert r.status is Status.INVALID_INPUT and r.reason == 'pull_not_in_map'


def with_status(nodes):
    """Synthetic map with node statuses set: nodes = [((pull, ih, ib, i1, i2, k), code)]."""
    data = synthetic()
    for idx, code in nodes:
        data.status[idx] = code
        data.capacity_N[idx] = np.nan
        data.slip_twist_scaled[idx] = np.nan
        data.reason[idx] = 1
    return CapacityMap(data)


def test_cell_touching_unsupported_node_has_no_value():
    g = small_grid()
    edge = with_status([((1, 1, 1, 0, 1, 1), UNSUP)])
    # with the valued-corner rule off (edge_min_weight > 1) the strict cell rule answers
    m = CapacityMap(edge.data, edge_min_weight=2.0)
    # inside the cell h 10..20, tb 0..10, l1 -20..20, l2 20..40, phi -10..0
    r = m.query(state(15, 5, 0, 30), math.radians(-5), 'backward')
    assert r.status is Status.UNSUPPORTED and r.capacity_N is None and r.slip_twist is None
    assert r.reason == 'cell_unsupported' and 'origin_outside' in r.detail
    # the same cell on the other pull orientation is fine
    assert m.query(state(15, 5, 0, 30), math.radians(-5), 'forward').ok
    # exactly on a valued neighbour node / face: the bad node has zero weight
    node = m.query(state(20, 0, -20, 20), math.radians(-10), 'backward')
    assert node.status is Status.OK
    face = m.query(state(15, 5, 0, 30), math.radians(0), 'backward')   # phi on a stored angle
    assert face.status is Status.OK
    assert g.phi[1] == pytest.approx(math.radians(-10))
    # by default the cell centre (valued weight 31/32 >= 0.9) answers the valued corners'
    # blend, flagged; a point next to the unsupported corner (its weight > 0.1) does not
    e = edge.query(state(15, 5, 0, 30), math.radians(-5), 'backward')
    assert e.ok and e.flags == ('edge_valued',) and e.capacity_N is not None
    near = edge.query(state(11, 1, -19, 21), math.radians(-9), 'backward')
    assert near.reason == 'cell_unsupported' and near.capacity_N is None


def test_conservative_priority_unsupported_over_degenerate():
    m = with_status([((1, 1, 1, 0, 1, 1), DEGEN), ((1, 2, 2, 1, 2, 2), UNSUP)])
    r = m.query(state(15, 5, 0, 30), math.radians(-5), 'backward')
    assert r.status is Status.UNSUPPORTED and r.capacity_N is None
    only_degen = m.query(state(12, 2, 0, 25), math.radians(-15), 'backward')
    assert only_degen.status is Status.DEGENERATE and only_degen.reason == 'cell_degenerate'


def test_twist_confidence_and_cancellation():
    data = synthetic()
    data.slip_twist_scaled[:, 2:] = (-0.6, 0.0, -0.8)   # h = 20 mm nodes opposed to the rest
    m = CapacityMap(data)
    low = m.query(state(16, 0, 0, 20), -0.1, 'backward')
    assert low.status is Status.OK and 'LOW twist confidence' in low.detail
    assert np.linalg.norm(low.slip_twist_scaled) == pytest.approx(1.0)
    zero = m.query(state(15, 0, 0, 20), -0.1, 'backward')   # halfway: exact cancellation
    assert zero.status is Status.DEGENERATE and zero.reason == 'twist_cancels'
    high = m.query(state(11, 0, 0, 20), -0.1, 'backward')
    assert 'LOW' not in high.detail


def test_batch_matches_single():
    m = with_status([((1, 1, 1, 0, 1, 1), UNSUP), ((0, 0, 0, 0, 0, 0), DEGEN)])
    g = m.grid
    rng = np.random.default_rng(3)
    lo = np.array([a[0] for a in g.axes] + [g.phi[0]])
    hi = np.array([a[-1] for a in g.axes] + [g.phi[-1]])
    span = hi - lo
    x = lo - 0.1 * span + 1.2 * span * rng.random((300, 5))
    x[:40, :4] = g.state_array()[rng.choice(g.n_states, 40)]     # some exactly on nodes
    x[5, 0] = np.nan
    for pull in g.pulls:
        b = m.query_batch(x[:, :4], x[:, 4], pull)
        for n in range(len(x)):
            r = m.query(AnchorState(*x[n, :4]), x[n, 4], pull)
            assert b.statuses()[n] is r.status, (n, r)
            if r.ok:
                # one query against the batched query (tests/tolerances.py); the unit twists
                # are interpolated like the capacity and normalised (a few eps more)
                assert b.capacity_N[n] == pytest.approx(r.capacity_N, rel=INTERPOLATION_RTOL,
                                                        abs=INTERPOLATION_ATOL)
                assert b.slip_twist_scaled[n] == pytest.approx(r.slip_twist_scaled,
                                                               abs=INTERPOLATION_RTOL)
                assert b.slip_twist[n] == pytest.approx(r.slip_twist, abs=INTERPOLATION_RTOL)
            else:
                assert np.isnan(b.capacity_N[n])


def test_query_is_fast(cmap):
    # Loose guard only (shared noisy machines); the budgeted figure is map_query_us
    # (rftgls_core/benchmarks/maps.py).
    import time
    s = state(12, 3, 5, 25)
    t0 = time.perf_counter()
    for _ in range(2000):
        cmap.query(s, -0.1, 'backward')
    assert (time.perf_counter() - t0) / 2000 < 200e-6


def test_support_edge_rule_is_opt_in_flagged_and_below_the_valued_blend():
    # A state whose cell touches unsupported nodes: no value by default (conservative cell
    # rule); with the opt-in support-edge rule a flagged value that never exceeds the largest
    # valued corner, and the same answer from the batch path.
    from rftgls_core.maps import CapacityMap, shipped_map_path
    strict = CapacityMap.load(shipped_map_path('minirquad'))
    edge = CapacityMap.load(shipped_map_path('minirquad'), support_edge=True)
    rng = np.random.default_rng(3)
    ax = strict.axes
    found = 0
    for _ in range(400):
        st = AnchorState(*(rng.uniform(ax[n][0], ax[n][-1])
                           for n in ('h', 'theta_b', 'theta_l1', 'theta_l2')))
        r = strict.query(st, 0.0, 'backward')
        if r.reason != 'cell_unsupported':
            continue
        e = edge.query(st, 0.0, 'backward')
        if not e.ok:
            continue
        found += 1
        assert e.flags == ('support_edge',) and e.capacity_N >= 0.0
        b = edge.query_batch([st.as_tuple()], [0.0], 'backward')
        assert b.support_edge[0] and b.capacity_N[0] == pytest.approx(
            e.capacity_N, rel=INTERPOLATION_RTOL)                 # single against batched query
        assert not strict.query_batch([st.as_tuple()], [0.0], 'backward').support_edge[0]
    assert found >= 5
