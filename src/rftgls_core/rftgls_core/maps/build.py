"""Building a capacity map: RobotPredictor at every grid node, in parallel, deterministically.

Work unit: a chunk of flat state indices (grid.py order), every n-th state of the grid
(neighbouring states cost alike, a strided chunk mixes cheap and dear ones, so the workers
finish together). For each state, each pull orientation is fitted once and queried at every
stored pull angle, and the node's support margin is taken on the fit's own wrenches, so a
node costs P surface fits. Each worker process (or Dask worker thread) builds its RobotPredictor
once and keeps it (`_predictor` cache), because the twist sphere and the numba kernels are
the expensive part to set up; the local pool is started once for both passes of a build,
its workers forked from a server that has the imports and kernels loaded (`worker_context`).

Determinism: chunks are fixed by the grid and chunk size, results are placed by state index
(never by completion order), the RFT kernels are serial, and nothing random is drawn, so the
same inputs give the same arrays on 1 worker, N local workers or a Dask cluster. Only the
build_time_utc attribute differs between builds.

Executors: workers == 1 runs in this process, its kernels on one thread; workers > 1 uses
this process and workers - 1 processes forked from a clean fork server (`worker_context`;
never a fork of this process, which may hold threads: tqdm's monitor, Dask, ROS),
`local_workers`; `scheduler` sends the same chunks to a Dask distributed scheduler at that
address.
"""
from __future__ import annotations

import json
import math
import multiprocessing
import os
import sys
import threading
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from .. import __version__
from ..predictor.live import RobotPredictor
from ..rft.media import Medium, get_medium
from ..robots.presets import get_robot
from ..surfaces.registry import DEFAULT_METHOD, DEFAULT_TWISTS
from ..surfaces.twist_sphere import TwistSphere
from ..types import Status
from .edge import (
    EDGE_MARGIN_TWISTS,
    fitted_wrenches,
    node_margin_gradient,
    node_support_margin,
    point_mesh_distance,
    signed_margin,
)
from .grid import MapGrid, default_grid
from .hdf5 import STATUS_NAMES, MapData, empty_answers


@dataclass(frozen=True)
class BuildSpec:
    """What a worker needs to rebuild the RobotPredictor: names and settings only (picklable)."""

    robot: str
    medium: Medium
    model: str = 'agarwal'
    method: str = DEFAULT_METHOD
    n_twists: int = DEFAULT_TWISTS
    backend: str = 'auto'

    def predictor(self) -> RobotPredictor:
        return RobotPredictor(get_robot(self.robot), self.medium, model=self.model,
                              method=self.method, n_twists=self.n_twists, backend=self.backend)


@dataclass(frozen=True)
class ChunkResult:
    """Answers for the states `ks`: arrays (len(ks), P, K) (+ (3,)); reasons as strings."""

    ks: np.ndarray
    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    status: np.ndarray
    reason: list
    support_margin: np.ndarray      # (len(ks), P), maps/edge.py
    # (len(ks), P): the origin's distance from the dense sphere's mesh where the fit's support
    # check evaluated that sphere (the edge pass's margin there, unsigned), else NaN
    dense_distance: np.ndarray


_local = threading.local()   # per thread (Dask runs tasks on threads), per process


def _predictor(spec: BuildSpec) -> RobotPredictor:
    cache = getattr(_local, 'predictors', None)
    if cache is None:
        cache = _local.predictors = {}
    if spec not in cache:
        cache[spec] = spec.predictor()
    return cache[spec]


def solve_chunk(spec: BuildSpec, grid: MapGrid, ks: Sequence[int]) -> ChunkResult:
    """Run the RobotPredictor at the flat state indices ks for every pull and pull angle."""
    predictor = _predictor(spec)
    sphere = TwistSphere.build(spec.n_twists)
    idx = np.asarray(ks, dtype=np.intp)
    n, P, K = len(idx), len(grid.pulls), len(grid.phi)
    cap = np.full((n, P, K), np.nan)
    ts = np.full((n, P, K, 3), np.nan)
    tr = np.full((n, P, K, 3), np.nan)
    status = np.zeros((n, P, K), dtype=np.uint8)
    reason = [[[''] * K for _ in range(P)] for _ in range(n)]
    margin = np.full((n, P), np.nan)
    dense_dist = np.full((n, P), np.nan)
    dense_sphere = TwistSphere.build(max(EDGE_MARGIN_TWISTS, spec.n_twists))
    for a, k in enumerate(idx.tolist()):
        state = grid.state(k)
        for p, pull in enumerate(grid.pulls):
            surface, failure = predictor.fit(state, pull)
            for j, r in enumerate(predictor.answers(surface, failure, grid.phi)):
                status[a, p, j] = STATUS_NAMES.index(r.status.value)
                reason[a][p][j] = r.reason
                if r.status.has_value:
                    cap[a, p, j] = r.capacity_N
                    ts[a, p, j] = r.slip_twist_scaled
                    tr[a, p, j] = r.slip_twist
            held = bool(np.isfinite(cap[a, p]).any())
            ws = fitted_wrenches(surface, sphere)
            margin[a, p] = (node_support_margin(predictor, sphere, state, pull, held) if ws is None
                            else signed_margin(ws, sphere, held))
            wsd = fitted_wrenches(surface, dense_sphere, support_check=True)
            if wsd is not None:
                dense_dist[a, p] = point_mesh_distance(wsd, dense_sphere.faces)
    return ChunkResult(idx, cap, ts, tr, status, reason, margin, dense_dist)


def solve_grad_chunk(spec: BuildSpec, grid: MapGrid,
                     work: tuple[np.ndarray, np.ndarray]
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edge-cell corners: support margin and its gradient on the dense EDGE_MARGIN_TWISTS
    sphere (edge.py), for work = (jobs (M, 3) = (flat state index, pull index, held 0/1),
    dense distances (M,): the first pass's, NaN where it has none): (jobs, margins (M,),
    gradients (M, 4)). A known distance is the margin (signed by held) without posing and
    evaluating the dense sphere once more: the same wrenches gave it."""
    jobs, known = work
    predictor = _predictor(spec)
    sphere = TwistSphere.build(max(EDGE_MARGIN_TWISTS, spec.n_twists))
    out = np.full((len(jobs), 4), np.nan)
    marg = np.full(len(jobs), np.nan)
    for a, (k, p, held) in enumerate(np.asarray(jobs, dtype=np.intp).tolist()):
        if np.isfinite(known[a]):
            marg[a] = known[a] if held else -known[a]
        else:
            marg[a] = node_support_margin(predictor, sphere, grid.state(k), grid.pulls[p],
                                          bool(held))
        out[a] = node_margin_gradient(predictor, sphere, grid, k, grid.pulls[p])
    return np.asarray(jobs), marg, out


def edge_cell_corners(held: np.ndarray) -> np.ndarray:
    """(P, Nh, Nb, N1, N2) bool: corners of the cells whose corners disagree on support
    (`held`, same shape). Only the edge-margin rule reads the margin gradient, and only in
    such cells, so the build computes it there alone."""
    shape = held.shape[1:]
    any_h = np.zeros((held.shape[0],) + tuple(n - 1 for n in shape), dtype=bool)
    all_h = np.ones_like(any_h)
    offsets = [tuple((c >> (3 - a)) & 1 for a in range(4)) for c in range(16)]
    for o in offsets:
        sl = (slice(None),) + tuple(slice(b, b + n - 1) for b, n in zip(o, shape))
        any_h |= held[sl]
        all_h &= held[sl]
    mixed = any_h & ~all_h
    out = np.zeros_like(held)
    for o in offsets:
        sl = (slice(None),) + tuple(slice(b, b + n - 1) for b, n in zip(o, shape))
        out[sl] |= mixed
    return out


# Chunks per worker in each pass: a pass ends when its last chunk does, so the other worker
# idles for up to one chunk (~1.5 s of a prototype build at 16) while a chunk's task overhead
# (pickling the spec and grid, the answers back) is milliseconds.
CHUNKS_PER_WORKER = 16


def chunk_indices(n_states: int, workers: int, per_worker: int = CHUNKS_PER_WORKER
                  ) -> list[np.ndarray]:
    """About `per_worker` chunks per worker (load balance vs. task overhead), each every
    n-th state: neighbouring states cost alike (a contiguous chunk of support-checked or
    closure-searched states takes several times one of unsupported states), so strided chunks
    cost alike and the workers finish together."""
    n_chunks = min(n_states, max(1, workers * per_worker))
    return [np.arange(c, n_states, n_chunks) for c in range(n_chunks)]


def _run_inline(spec, grid, chunks, fn=solve_chunk) -> Iterator:
    for c in chunks:
        yield fn(spec, grid, c)


class LocalWorkers:
    """`workers` workers for every pass of one build: this process and workers - 1 worker
    processes (`worker_context`) started once. A worker's start costs little once the fork
    server runs (~1.2 s of CPU for the server's imports and kernels, once per session; more
    wall time on a busy machine), and the process that has them already works too (its
    kernels on one thread meanwhile, as the others' are).

    Feeding: each worker process has QUEUED chunks handed out beyond the one it runs, counted
    after the finished ones are collected, so a worker that finishes while this process is
    inside a chunk of its own finds the next one waiting (counting finished but uncollected
    chunks as handed out left the worker idle for a quarter of a described build). When no
    chunk is left to hand out, this process takes back the last handed-out chunk no worker
    has begun (cancelled there: computed once), and only while no worker has delivered
    anything yet (a slow start) also one a worker holds (the same numbers, whoever computes
    them first): a pass never waits for a slow start."""

    QUEUED = 3

    def __init__(self, pool: ProcessPoolExecutor, processes: int):
        self.pool, self.processes = pool, processes

    def run(self, spec, grid, chunks, fn=solve_chunk) -> Iterator:
        """Results of fn on every chunk, each once, in completion order."""
        todo = deque(chunks)
        running: dict[Future, object] = {}
        taken: set[Future] = set()      # chunks this process computes too (a slow start)
        delivered = False               # a worker process has returned a chunk
        try:
            while todo or len(taken) < len(running):
                for fut in [f for f in running if f.done()]:
                    c = running.pop(fut)
                    if fut in taken:
                        taken.discard(fut)
                    elif fut.cancelled():     # taken back below: computed here
                        yield fn(spec, grid, c)
                    else:
                        delivered = True
                        yield fut.result()
                while todo and len(running) - len(taken) < self.QUEUED * self.processes:
                    c = todo.popleft()
                    running[self.pool.submit(fn, spec, grid, c)] = c
                if todo:
                    yield fn(spec, grid, todo.popleft())
                    continue
                left = [f for f in running if f not in taken]
                if any(f.cancel() for f in reversed(left)):
                    continue                  # the cancelled chunk is computed above
                if left and not delivered:
                    taken.add(left[0])
                    yield fn(spec, grid, running[left[0]])
                elif left:
                    wait(left, return_when=FIRST_COMPLETED)
        finally:
            for fut in running:
                fut.cancel()


# Modules a worker process imports before its first task (maps/build.py's worker functions,
# the described and gait map builds', and worker_preload, which loads the compiled kernels):
# ~0.9 s + ~0.2 s of CPU per process, paid once per session in the fork server (below).
WORKER_MODULES = ['rftgls_core.maps.build', 'rftgls_core.maps.described_build',
                  'rftgls_core.planning.gait_map', 'rftgls_core.maps.worker_preload']


def worker_context() -> multiprocessing.context.BaseContext:
    """The start method of local worker processes: 'forkserver' where there is one (Linux,
    macOS), else 'spawn'. The fork server is a fresh single-threaded process started from
    scratch like a spawned one (so nothing of this process's threads is forked) that imports
    WORKER_MODULES once; each worker is then a fork of it and starts with them imported. The
    server lives as long as this process, so a session's later pools (the bench's second
    build, a gait map after a capacity map) start their workers in milliseconds."""
    if 'forkserver' not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context('spawn')
    ctx = multiprocessing.get_context('forkserver')
    # read when the server starts (this process's first forkserver pool); later calls no-ops
    ctx.set_forkserver_preload(WORKER_MODULES)
    return ctx


@contextmanager
def local_workers(workers: int) -> Iterator[LocalWorkers]:
    """LocalWorkers for a build on `workers` >= 2 workers (on leaving, chunks not started are
    cancelled and a chunk still running elsewhere is not waited for)."""
    pool = ProcessPoolExecutor(max_workers=workers - 1, mp_context=worker_context())
    try:
        with one_thread():
            yield LocalWorkers(pool, workers - 1)
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


@contextmanager
def one_thread() -> Iterator[None]:
    """The RFT kernels of this thread on one thread inside the block: a worker of a build is
    one core, whether the others are processes (they take the other cores) or there are none
    (`workers=1`: otherwise its large kernel calls, about half of a prototype build's CPU, would
    run on every core, and one worker would not be one)."""
    from ..rft import kernels
    before = kernels.threads()
    if kernels.AVAILABLE:
        kernels.set_threads(1)
    try:
        yield
    finally:
        if kernels.AVAILABLE:
            kernels.set_threads(before)


def probe_scheduler(address: str, timeout_s: float = 3.0) -> None:
    """Fail in seconds (OSError, one line) unless a TCP connection to the Dask scheduler at
    `address` ('tcp://HOST:PORT') opens within timeout_s: Dask's client retries a refused or
    silent address for its whole timeout. ValueError for an address that is not one."""
    import socket
    from urllib.parse import urlsplit
    u = urlsplit(address if '://' in address else f'tcp://{address}')
    if u.scheme == 'inproc':     # a scheduler in this process (tests): nothing to reach
        return
    try:
        host, port = u.hostname, u.port
    except ValueError:
        host = port = None
    if u.scheme not in ('tcp', 'tls') or not host or port is None:
        raise ValueError(f'--scheduler {address!r}: want tcp://HOST:PORT')
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise OSError(f'cannot reach Dask scheduler {address} ({reason}; waited at most '
                      f'{timeout_s:g} s)') from None


def _run_dask(spec, grid, chunks, address: str, timeout_s: float,
              fn=solve_chunk) -> Iterator:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError as exc:  # pragma: no cover - dask is in the venv
        raise ValueError(f'--scheduler needs the optional dask[distributed] (pip install '
                         f'"dask[distributed]"): {exc}') from None
    try:
        client = Client(address, timeout=timeout_s, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise OSError(f'cannot reach Dask scheduler {address}: {exc}') from None
    try:
        futures = [client.submit(fn, spec, grid, c, pure=False) for c in chunks]
        try:
            # loop= explicitly: the client is not made the process-wide default.
            for fut in dask_completed(futures, loop=client.loop):
                yield fut.result()
        finally:
            client.cancel(futures)
    finally:
        client.close()


@dataclass
class _Answers:
    """Every state's answers, (S, P, K) (+ (3,)), reasons as strings, margins (S, P)."""

    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    status: np.ndarray
    reasons: np.ndarray
    support_margin: np.ndarray
    dense_distance: np.ndarray     # (S, P), ChunkResult.dense_distance


def _solve_states(run, spec: BuildSpec, grid: MapGrid, workers: int, progress: bool
                  ) -> _Answers:
    """First pass: every state, in chunks (`chunk_indices`), placed by state index."""
    P, K, S = len(grid.pulls), len(grid.phi), grid.n_states
    cap, ts, tr, status, reasons = empty_answers((S, P, K), 3)
    margin = np.full((S, P), np.nan)
    dense_dist = np.full((S, P), np.nan)
    from tqdm import tqdm
    with tqdm(total=S, unit='state', file=sys.stderr, disable=not progress,
              desc=f'map {spec.robot}/{spec.medium.name}', dynamic_ncols=True) as bar:
        for r in run(chunk_indices(S, workers)):
            cap[r.ks], ts[r.ks], tr[r.ks], status[r.ks] = (r.capacity_N, r.slip_twist_scaled,
                                                           r.slip_twist, r.status)
            margin[r.ks] = r.support_margin
            dense_dist[r.ks] = r.dense_distance
            for a, k in enumerate(r.ks.tolist()):
                for p in range(P):
                    reasons[k, p, :] = r.reason[a][p]
            bar.update(len(r.ks))
    return _Answers(cap, ts, tr, status, reasons, margin, dense_dist)


def _edge_pass(run, grid: MapGrid, answers: _Answers, workers: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Second pass: at the corners of cells that straddle the support edge (the only cells
    whose rule reads them) the margin again and its gradient, on the dense sphere of the
    weight-held check; the gradient is NaN elsewhere. Returns (margin (S, P), grad (S, P, 4))."""
    P, S = len(grid.pulls), grid.n_states
    margin = answers.support_margin.copy()
    valued_codes = [STATUS_NAMES.index(st.value) for st in Status if st.has_value]
    held = np.asarray(np.isin(answers.status, valued_codes).any(axis=2)).T.reshape(
        (P,) + grid.state_shape)
    need = edge_cell_corners(held) & np.isfinite(margin.T.reshape(held.shape))
    pk = np.argwhere(need.reshape(P, -1))               # (M, 2) = (pull, flat state)
    held_flat = held.reshape(P, -1)
    jobs = (np.column_stack([pk[:, 1], pk[:, 0], held_flat[pk[:, 0], pk[:, 1]]])
            if len(pk) else np.zeros((0, 3), np.intp))
    grad = np.full((S, P, 4), np.nan)
    if len(jobs):
        size = max(1, math.ceil(len(jobs) / max(1, workers * CHUNKS_PER_WORKER)))
        known = answers.dense_distance[jobs[:, 0], jobs[:, 1]]
        for js, m1, g4 in run([(jobs[i:i + size], known[i:i + size])
                               for i in range(0, len(jobs), size)], solve_grad_chunk):
            margin[js[:, 0], js[:, 1]] = m1
            grad[js[:, 0], js[:, 1]] = g4
    return margin, grad


def default_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def build_map(robot: str, medium: str | Medium, grid: MapGrid | None = None, *,
              method: str = DEFAULT_METHOD, model: str = 'agarwal',
              n_twists: int = DEFAULT_TWISTS, workers: int | None = None,
              scheduler: str | None = None, progress: bool = False, command: str = '',
              backend: str = 'auto', scheduler_timeout_s: float = 10.0) -> MapData:
    """Compute a map in memory (save it with hdf5.save_map).

    robot: preset name (robots.presets); medium: preset name or a Medium; grid: default_grid
    for the robot when None; method/model/n_twists/backend: RobotPredictor settings;
    workers: local processes (default: all usable cores; 1 = in this process);
    scheduler: Dask scheduler address ('tcp://host:port'), overrides workers;
    progress: tqdm bar on stderr; command: recorded in the file's build_command.
    """
    med = get_medium(medium) if isinstance(medium, str) else medium
    grid = default_grid(robot) if grid is None else grid
    spec = BuildSpec(robot=get_robot(robot).name, medium=med, model=model, method=method,
                     n_twists=int(n_twists), backend=backend)
    probe = spec.predictor()   # fail fast (unknown method/model) before any worker starts
    if scheduler:
        probe_scheduler(scheduler)   # an unreachable cluster fails now, in seconds
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f'workers must be >= 1, got {workers}')
    with ExitStack() as stack:
        local = (stack.enter_context(local_workers(min(workers, grid.n_states)))
                 if workers > 1 and not scheduler else None)
        if local is None and not scheduler:
            stack.enter_context(one_thread())   # one worker is one core, as in a pool

        def run(chunks, fn=solve_chunk) -> Iterator:
            if scheduler:
                return _run_dask(spec, grid, chunks, scheduler, scheduler_timeout_s, fn)
            if local is None or len(chunks) == 1:
                return _run_inline(spec, grid, chunks, fn)
            return local.run(spec, grid, chunks, fn)

        answers = _solve_states(run, spec, grid, 4 if scheduler else workers, progress)
        margin, grad = _edge_pass(run, grid, answers, 4 if scheduler else workers)
    P = len(grid.pulls)
    cap, ts, tr, status = (answers.capacity_N, answers.slip_twist_scaled, answers.slip_twist,
                           answers.status)
    reasons = answers.reasons
    # Sorted table: the reason codes do not depend on completion order.
    names = tuple(sorted(set(reasons.reshape(-1).tolist()) | {''}))
    code_of = {n: i for i, n in enumerate(names)}
    reason = np.vectorize(code_of.__getitem__, otypes=[np.uint8])(reasons)

    def arrange(a: np.ndarray) -> np.ndarray:
        # (S, P, K, ...) -> (P, Nh, Nb, N1, N2, K, ...)
        a = np.moveaxis(a, 1, 0)
        return a.reshape((P,) + grid.state_shape + a.shape[2:])

    describe = probe.describe()
    attrs = {'robot': spec.robot, 'medium': med.name, 'method': method,
             'rft_model': probe.stress_model.name, 'n_twists': int(n_twists),
             'scaling_force_N': float(probe.scaling.force_N),
             'scaling_length_m': float(probe.scaling.length_m),
             'package_version': __version__, 'build_command': command,
             'provenance_json': json.dumps({**describe, 'backend': backend}, sort_keys=True),
             'build_time_utc': datetime.now(UTC).isoformat(timespec='seconds')}
    return MapData(grid=grid, capacity_N=arrange(cap).astype(np.float32),
                   slip_twist_scaled=arrange(ts).astype(np.float32),
                   slip_twist=arrange(tr).astype(np.float32),
                   status=arrange(status), reason=arrange(reason), reason_names=names,
                   attrs=attrs, support_margin=arrange(margin).astype(np.float32),
                   support_margin_grad=arrange(grad).astype(np.float32))


def spec_from_map(data: MapData) -> BuildSpec:
    """The BuildSpec recorded in a map's provenance (to rebuild nodes for checking)."""
    prov = json.loads(data.attrs['provenance_json'])
    return BuildSpec(robot=data.attrs['robot'], medium=Medium(**prov['medium']),
                     model=data.attrs['rft_model'], method=data.attrs['method'],
                     n_twists=int(data.attrs['n_twists']), backend=prov.get('backend', 'auto'))


def status_counts(data: MapData) -> dict[str, int]:
    """How many answers have each status (for `map info` and build summaries)."""
    counts = np.bincount(data.status.reshape(-1), minlength=len(STATUS_NAMES))
    return {STATUS_NAMES[i]: int(c) for i, c in enumerate(counts) if c}


__all__ = ['BuildSpec', 'ChunkResult', 'build_map', 'solve_chunk', 'chunk_indices',
           'spec_from_map', 'status_counts', 'default_workers']
