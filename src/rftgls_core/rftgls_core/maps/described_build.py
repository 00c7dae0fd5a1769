"""Building a described map: posed.PosedAnchorSolver at every node of a DescribedGrid.

As maps/build.py does for the robot maps: fixed chunks of flat state indices, answers placed
by state index (never by completion order) and serial kernels, so any number of local workers
gives the same arrays; the file format and the query are maps/described.py.
"""
from __future__ import annotations

import dataclasses
import json
import sys
import threading
from contextlib import ExitStack
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from .. import __version__
from ..rft.media import Medium
from ..types import Status
from .described import DescribedGrid, DescribedMapData, description_grid
from .hdf5 import STATUS_NAMES, empty_answers


@dataclass(frozen=True)
class DescribedSpec:
    """What a worker needs to pose and solve a description (picklable: the description is
    named by its YAML path and identity, re-read once per worker and checked)."""

    path: str
    sha256: str
    medium: Medium
    model: str = 'agarwal'
    method: str = 'direct'
    n_twists: int | None = None
    space: str = 'auto'


_local = threading.local()   # per thread and process: (description, PosedAnchorSolver) by spec


def _solver(spec: DescribedSpec):
    from ..description import DescriptionError, load_description
    from ..posed import PosedAnchorSolver
    cache = getattr(_local, 'solvers', None)
    if cache is None:
        cache = _local.solvers = {}
    if spec not in cache:
        desc = load_description(spec.path)
        if desc.sha256 != spec.sha256:
            raise DescriptionError(f'{spec.path}: changed during the build (identity '
                                   f'{desc.sha256[:12]}, the build started with '
                                   f'{spec.sha256[:12]})')
        cache[spec] = (desc, PosedAnchorSolver(spec.medium, model=spec.model,
                                               method=spec.method, n_twists=spec.n_twists,
                                               space=spec.space))
    return cache[spec]


def solve_described_chunk(spec: DescribedSpec, grid: DescribedGrid, ks) -> tuple:
    """Answers at the flat state indices ks: (ks, capacity (n, P, K), scaled twists
    (n, P, K, 6), raw twists, status codes, reasons (n, P, K) object)."""
    desc, sm = _solver(spec)
    idx = np.asarray(ks, dtype=np.intp)
    P, K = len(grid.pulls), len(grid.phi)
    cap, ts, tr, status, reasons = empty_answers((len(idx), P, K), 6)
    for a, k in enumerate(idx.tolist()):
        values = grid.values(k)
        outside = desc.violations(values)
        for p, pull in enumerate(grid.pulls):
            if outside:   # a map range beyond the physical one: no answer
                status[a, p, :] = STATUS_NAMES.index(Status.INVALID_INPUT.value)
                reasons[a, p, :] = 'not_a_pose'
                continue
            # one fit per node and pull, asked at every stored angle
            answers = sm.solve_many(desc.pose(values, pull), grid.phi, 0.0)
            for j, r in enumerate(answers):
                status[a, p, j] = STATUS_NAMES.index(r.status.value)
                reasons[a, p, j] = r.reason
                if r.status.has_value and r.capacity_N is not None:
                    cap[a, p, j] = r.capacity_N
                    ts[a, p, j] = r.slip_twist_scaled
                    tr[a, p, j] = r.slip_twist
    return idx, cap, ts, tr, status, reasons


def build_described_map(desc, medium, grid: DescribedGrid | None = None, *,
                        method: str = 'direct', model: str = 'agarwal',
                        n_twists: int | None = None, command: str = '',
                        progress: bool = False, workers: int = 1) -> DescribedMapData:
    """Answers of posed.PosedAnchorSolver at every node of `grid` (default: the description's map
    ranges). desc: an AnchorDescription; medium: a Medium. workers: local processes (1 = in
    this process), as maps/build.py does for the robot maps (fixed chunks placed by state
    index, serial kernels: the same arrays on any number of workers); progress: a tqdm bar
    on stderr over the states."""
    from tqdm import tqdm

    from ..posed import PosedAnchorSolver
    from .build import _run_inline, chunk_indices, local_workers, one_thread
    grid = description_grid(desc) if grid is None else grid
    if grid.names != desc.state_names:
        raise ValueError(f'grid axes {grid.names} are not the state of {desc.name} '
                         f'{desc.state_names}')
    workers = int(workers)
    if workers < 1:
        raise ValueError(f'workers must be >= 1, got {workers}')
    space = 'sagittal' if desc.symmetry == 'sagittal' else 'auto'
    spec = DescribedSpec(str(Path(desc.source).resolve()), desc.sha256, medium, model, method,
                         n_twists, space)
    sm = PosedAnchorSolver(medium, model=model, method=method, n_twists=n_twists, space=space)
    cache = getattr(_local, 'solvers', None)
    if cache is None:
        cache = _local.solvers = {}
    cache[spec] = (desc, sm)   # this process answers with the description it was given
    P, K, S = len(grid.pulls), len(grid.phi), grid.n_states
    chunks = chunk_indices(S, workers)
    cap, ts, tr, status, reasons = empty_answers((P, S, K), 6)
    with ExitStack() as stack, tqdm(total=S, unit='state', file=sys.stderr,
                                    disable=not progress, desc=f'map {desc.name}/{medium.name}',
                                    dynamic_ncols=True) as bar:
        if workers == 1 or len(chunks) == 1:
            stack.enter_context(one_thread())   # one worker is one core, as in a pool
            results = _run_inline(spec, grid, chunks, solve_described_chunk)
        else:
            results = stack.enter_context(local_workers(min(workers, len(chunks)))).run(
                spec, grid, chunks, solve_described_chunk)
        for ks, c, t, r, st, rs in results:
            # (n, P, K) -> (P, n, K): placed by state index, never by completion order
            cap[:, ks], ts[:, ks], tr[:, ks] = (np.swapaxes(c, 0, 1), np.swapaxes(t, 0, 1),
                                                np.swapaxes(r, 0, 1))
            status[:, ks], reasons[:, ks] = np.swapaxes(st, 0, 1), np.swapaxes(rs, 0, 1)
            bar.update(len(ks))
    names = tuple(sorted(set(reasons.reshape(-1).tolist()) | {''}))
    code_of = {n: i for i, n in enumerate(names)}
    reason = np.vectorize(code_of.__getitem__, otypes=[np.uint8])(reasons)
    shape = grid.shape

    def arrange(a: np.ndarray, extra=()) -> np.ndarray:
        return a.reshape(shape + extra)
    attrs = {'description_sha256': desc.sha256, 'description_name': desc.name,
             'state_names': ','.join(grid.names), 'medium': medium.name, 'method': method,
             'rft_model': sm.stress_model.name, 'n_twists': int(sm.n_twists), 'space': space,
             'char_length_m': float(desc.char_length),
             'provenance_json': json.dumps({'medium': dataclasses.asdict(medium)},
                                           sort_keys=True),
             'package_version': __version__, 'build_command': command,
             'build_time_utc': datetime.now(UTC).isoformat(timespec='seconds')}
    return DescribedMapData(grid, arrange(cap).astype(np.float32),
                            arrange(ts, (6,)).astype(np.float32),
                            arrange(tr, (6,)).astype(np.float32), arrange(status),
                            arrange(reason), names, attrs)
