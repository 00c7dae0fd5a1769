"""Building maps with the real RobotPredictor: determinism across executors, CLI, shipped files."""
import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rftgls_core.maps import CapacityMap, MapGrid, build_map, load_map, save_map
from rftgls_core.maps.build import solve_chunk, spec_from_map
from rftgls_core.maps.grid import default_grid
from rftgls_core.maps.hdf5 import STATUS_NAMES, VOLATILE_ATTRS
from rftgls_core.types import Status

REPO = Path(__file__).resolve().parents[2]
SHIPPED = {'prototype_glass_beads.h5': ('prototype', 'glass_beads'),
           'minirquad_m90_sand.h5': ('minirquad', 'm90_sand')}
CLI = [sys.executable, '-m', 'rftgls_core.cli.main']
TWISTS = 200


def tiny_grid():
    # h = 40 mm leaves little buried: expect some unsupported answers next to ok ones
    return MapGrid.from_degrees([10, 40], [0, 20], [-20, 20], [0, 30], [-20, 0])


def file_contents(path):
    """Every dataset and every non-volatile attribute (the determinism contract)."""
    out = {}
    with h5py.File(path) as f:
        out['/attrs'] = {k: f.attrs[k] for k in f.attrs if k not in VOLATILE_ATTRS}

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = (obj[()], obj.dtype.str, dict(obj.attrs))
        f.visititems(visit)
    return out


def assert_same_contents(a, b):
    ca, cb = file_contents(a), file_contents(b)
    assert ca.keys() == cb.keys()
    for key in ca:
        if key == '/attrs':
            assert set(ca[key]) == set(cb[key])
            for k in ca[key]:
                assert np.array_equal(ca[key][k], cb[key][k]), k
            continue
        (va, da, aa), (vb, db, ab) = ca[key], cb[key]
        assert da == db, key
        np.testing.assert_array_equal(va, vb, err_msg=key)
        assert aa.keys() == ab.keys()


@pytest.fixture(scope='module')
def inline_map(tmp_path_factory):
    data = build_map('prototype', 'glass_beads', tiny_grid(), n_twists=TWISTS, workers=1,
                     command='test')
    return save_map(tmp_path_factory.mktemp('maps') / 'inline.h5', data)


def test_inline_build_is_sane(inline_map):
    data = load_map(inline_map)
    assert data.status.shape == (2, 2, 2, 2, 2, 2)
    assert data.capacity_N.dtype == np.float32
    codes = set(np.unique(data.status).tolist())
    assert STATUS_NAMES.index('ok') in codes
    valued = data.status == STATUS_NAMES.index('ok')
    assert np.all(data.capacity_N[valued] > 0) and np.all(np.isnan(data.capacity_N[~valued]))
    assert data.attrs['n_twists'] == TWISTS and data.attrs['build_command'] == 'test'
    prov = data.provenance
    assert prov['robot']['mass_kg'] == 0.12 and prov['medium']['name'] == 'glass_beads'
    # a node query returns the node value (float32 storage)
    g = data.grid
    k = np.argwhere(valued)[0]
    from rftgls_core.types import AnchorState
    st = AnchorState(*(float(a[i]) for a, i in zip(g.axes, k[1:5])))
    r = CapacityMap(data).query(st, float(g.phi[k[5]]), g.pulls[k[0]])
    assert r.status is Status.OK and r.capacity_N == float(data.capacity_N[tuple(k)])


def test_process_pool_gives_identical_file(inline_map, tmp_path):
    data = build_map('prototype', 'glass_beads', tiny_grid(), n_twists=TWISTS, workers=2,
                     command='test')
    assert_same_contents(inline_map, save_map(tmp_path / 'pool.h5', data))


def test_dask_local_cluster_gives_identical_file(inline_map, tmp_path):
    distributed = pytest.importorskip('dask.distributed')
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        data = build_map('prototype', 'glass_beads', tiny_grid(), n_twists=TWISTS,
                         scheduler=cluster.scheduler_address, command='test')
    assert_same_contents(inline_map, save_map(tmp_path / 'dask.h5', data))


def test_cli_build_info_and_errors(tmp_path):
    out = tmp_path / 'cli.h5'
    args = ['map', 'build', '--robot', 'prototype', '--medium', 'glass_beads', '--out', str(out),
            '--h', '10,20', '--theta-b', '0,10', '--theta-l1=-20,0', '--theta-l2', '0,20',
            '--phi=-20,0', '--n-twists', '100', '--workers', '1', '--pulls', 'backward']
    res = subprocess.run(CLI + args, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert '16 states' in res.stdout
    m = CapacityMap.load(out)
    assert m.pulls == ('backward',)
    cmd = m.provenance['build_command']
    assert cmd.startswith('rftgls map build --robot prototype') and '--theta-l1=-20,0' in cmd
    info = subprocess.run(CLI + ['map', 'info', str(out), '--json'], capture_output=True,
                          text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    d = json.loads(info.stdout)
    assert d['schema_version'] == 2 and d['axes']['h']['values_mm'] == [10, 20]
    out.write_bytes(out.read_bytes()[:300])
    bad = subprocess.run(CLI + ['map', 'info', str(out)], capture_output=True, text=True,
                         timeout=60)
    assert bad.returncode == 2 and bad.stderr.count('\n') == 1 and 'corrupt' in bad.stderr
    unknown = subprocess.run(CLI + ['map', 'build', '--robot', 'prototype', '--medium', 'mud',
                                    '--out', str(tmp_path / 'x.h5')],
                             capture_output=True, text=True, timeout=60)
    assert unknown.returncode == 2 and 'unknown medium' in unknown.stderr


def test_accuracy_report_runs(inline_map):
    from rftgls_core.maps.accuracy import accuracy_report
    rep = accuracy_report(CapacityMap.load(inline_map), samples=2, seed=1, reference='twist-mesh')
    assert rep.n_states == 3 and rep.reference == 'twist-mesh'
    assert rep.n_compared + rep.status_mismatch > 0
    if rep.n_compared:
        assert rep.capacity_pct.worst >= rep.capacity_pct.p95 >= 0


@pytest.mark.parametrize('name', sorted(SHIPPED))
def test_shipped_map_matches_a_rebuild(name):
    path = REPO / 'maps' / name
    if not path.exists():
        pytest.skip(f'{path} not built yet')
    assert path.stat().st_size < 2_000_000
    data = load_map(path)
    robot, medium = SHIPPED[name]
    assert (data.attrs['robot'], data.attrs['medium']) == (robot, medium)
    assert data.grid == default_grid(robot)
    assert data.attrs['build_command'].startswith(f'rftgls map build --robot {robot}')
    g = data.grid
    # three nodes: first, last, and one with an answer without value if there is one
    bad = np.argwhere(data.status[0] != STATUS_NAMES.index('ok'))
    ks = [0, g.n_states - 1]
    if len(bad):
        ks.append(int(np.ravel_multi_index(tuple(bad[0][:4]), g.state_shape)))
    ks.append(g.n_states // 2)
    res = solve_chunk(spec_from_map(data), g, ks[:3])
    flat = lambda a: np.moveaxis(a.reshape((len(g.pulls), g.n_states) + a.shape[5:]), 0, 1)
    np.testing.assert_array_equal(res.status, flat(data.status)[ks[:3]])
    np.testing.assert_array_equal(res.capacity_N.astype(np.float32), flat(data.capacity_N)[ks[:3]])
    np.testing.assert_array_equal(res.slip_twist_scaled.astype(np.float32),
                                  flat(data.slip_twist_scaled)[ks[:3]])


def _chunk_scheduler_run(pool, chunks, fn):
    from rftgls_core.maps.build import LocalWorkers
    return list(LocalWorkers(pool, 1).run(None, None, chunks, fn))


def test_the_chunk_scheduler_delivers_every_chunk_once_and_computes_none_twice():
    """This process and a worker (a thread pool standing in for the process pool: the same
    futures) share 40 chunks; every result comes back once, and a chunk the worker had not
    begun when this process ran out is taken back (cancelled there), not computed twice."""
    import threading
    import time
    from concurrent.futures import ThreadPoolExecutor
    ran: list[tuple[int, bool]] = []
    main = threading.get_ident()
    worker_delivered = threading.Event()

    def fn(spec, grid, c):
        here = threading.get_ident() == main
        if here:
            # the worker has started (else taking a chunk it holds is right: a slow start)
            worker_delivered.wait(30)
        time.sleep(0.002 * (1 + c % 3))
        ran.append((c, here))
        if not here:
            worker_delivered.set()
        return c
    with ThreadPoolExecutor(max_workers=1) as pool:
        got = _chunk_scheduler_run(pool, list(range(40)), fn)
    assert sorted(got) == list(range(40))
    assert sorted(c for c, _ in ran) == list(range(40))         # none computed twice
    assert any(here for _, here in ran) and not all(here for _, here in ran)


def test_the_chunk_scheduler_does_not_wait_for_a_worker_that_has_not_started():
    """A worker that has not begun (a slow start) holds no chunk hostage: this process
    computes all of them, and each result still comes back once."""
    import threading
    from concurrent.futures import ThreadPoolExecutor
    release = threading.Event()

    def fn(spec, grid, c):
        if threading.current_thread() is not threading.main_thread():
            release.wait(30)            # the worker starts only after the pass
        return c
    with ThreadPoolExecutor(max_workers=1) as pool:
        got = _chunk_scheduler_run(pool, list(range(12)), fn)
        release.set()
    assert sorted(got) == list(range(12))
