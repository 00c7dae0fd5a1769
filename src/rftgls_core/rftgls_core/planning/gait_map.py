"""The gait map: the gait space precomputed, so a plan onboard is a table look-up.

Schema `rftgls.gait_map`, version 1 (N gaits, R runs of the spread, K tether angles; SI):

    /                     root attributes: schema, schema_version, robot, medium,
                          inputs_sha256 (predict.PlanInputs.inputs_sha256: what the answers
                          depend on), inputs_json, package_version, build_command,
                          build_time_utc (the only volatile one), content_sha256
    /gaits                (N, 5) float64: retract l1, l2, final l1, l2 (rad), speed (rad/s)
    /gait_names           (N,) str: 'DH', 'DL', 'SH' or ''
    /runnable             (N,) str: '' or why the robot cannot run the gait
    /phi                  (K,) float64, rad
    /run_labels           (R,) str; /pairs (P, 2) int: the (+, -) runs of each input
    /status, /reason      (N, R) str: each run's status and reason ('not_run' after a failure)
    /pose                 (N, R, 4) float64: h m, theta_b, theta_l1, theta_l2 rad (NaN: none)
    /energy_elec_J        (N, R) float64
    /capacity_N           (N, R, K) float64 (NaN: none); /cap_reason (N, R, K) str
    /steps                (N, R) int64: steps simulated (0: a run copied, spread.py)

The map stores the runs, not the bound: the planner computes each gait's answer from them
(bound.answer) at the confidence asked, with the same code as the live planner, so a map
answer equals the live one at its gaits (docs/design/burrow-planner.md, "The gait map"). It
answers only its own gaits and tether angles and only for the inputs whose hash it carries;
anything else goes to the live simulation. `load` recomputes content_sha256 and refuses a
mismatch; a shipped map must also match the hash recorded here (SHIPPED_SHA256).
"""
from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterable, Iterator, Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import h5py
import numpy as np

from rftgls_conventions.safe_write import atomic_write

from ..maps.errors import MapFileError
from ..maps.hdf5 import ContentHash, check_dataset_size
from ..maps.shipped import maps_dir, regular_map_file
from .gaits import GaitPoint
from .predict import GaitRuns, PlanInputs, predict_gait

SCHEMA = 'rftgls.gait_map'
SCHEMA_VERSION = 1
HASH_ATTR = 'content_sha256'
ANSWER_ATTRS = ('robot', 'medium', 'inputs_sha256', 'inputs_json')
INFO_ATTRS = ('package_version', 'build_command')
VOLATILE_ATTRS = ('build_time_utc',)
STRING_SETS = ('gait_names', 'runnable', 'run_labels', 'status', 'reason', 'cap_reason')
NUMBER_SETS = ('gaits', 'phi', 'pairs', 'pose', 'energy_elec_J', 'capacity_N', 'steps')

# The shipped gait maps (in maps_dir()), one per sled the robot burrows tied to, and their
# content hashes, recorded when written (maps/README.md has the commands). `load` refuses a
# shipped file that does not match.
SHIPPED = {'minirquad': ('minirquad_m90_sand_gaits_sled400g.h5',
                         'minirquad_m90_sand_gaits_sled600g.h5')}
SHIPPED_SHA256: dict[str, str] = {
    'minirquad_m90_sand_gaits_sled400g.h5':
        'bd04c38edef2948e2362a222fb971a408d0a0dc6ec18a8240d93102fed46765f',
    'minirquad_m90_sand_gaits_sled600g.h5':
        '714719ef9282f2240714221e78c58ec996be867be189d8535cce07edb56799ac',
}


@dataclass
class GaitMap:
    """A gait map in memory (module doc for the arrays)."""

    attrs: dict
    arrays: dict

    # ------------------------------------------------------------------ identity
    @property
    def inputs_sha256(self) -> str:
        return str(self.attrs['inputs_sha256'])

    @property
    def phis(self) -> np.ndarray:
        return self.arrays['phi']

    def gaits(self) -> list[GaitPoint]:
        return [GaitPoint.from_array(a, str(n)) for a, n in
                zip(self.arrays['gaits'], self.arrays['gait_names'])]

    def answers_for(self, inputs: PlanInputs) -> str | None:
        """None when the map answers for `inputs` (the same inputs hash, every tether angle
        asked among its own), else why not (one line)."""
        if self.inputs_sha256 != inputs.inputs_sha256():
            return (f'built for other inputs (inputs hash {self.inputs_sha256[:12]}..., asked '
                    f'{inputs.inputs_sha256()[:12]}...)')
        missing = [p for p in inputs.phis if not np.any(np.abs(self.phis - p) < 1e-9)]
        if missing:
            return (f'holds phi {[round(math.degrees(p), 3) for p in self.phis]} deg, not '
                    f'{[round(math.degrees(p), 3) for p in missing]}')
        return None

    # ------------------------------------------------------------------ query
    def runs(self, phis: Sequence[float]) -> list[GaitRuns]:
        """Every gait's runs at the tether angles `phis` (each one of the map's)."""
        idx = [int(np.argmin(np.abs(self.phis - p))) for p in phis]
        a = self.arrays
        pairs = [(int(p[0]), int(p[1])) for p in a['pairs']]
        labels = [str(s) for s in a['run_labels']]
        out = []
        for n in range(len(a['gaits'])):
            out.append(GaitRuns(
                [str(s) for s in a['status'][n]], [str(s) for s in a['reason'][n]],
                a['pose'][n], a['energy_elec_J'][n], a['capacity_N'][n][:, idx],
                [[str(a['cap_reason'][n, r, k]) for k in idx] for r in range(len(labels))],
                pairs, labels, tuple(float(p) for p in phis),
                str(a['runnable'][n]) or None, [int(v) for v in a['steps'][n]]))
        return out


# ---------------------------------------------------------------------- build
def _solve(inputs: PlanInputs, gaits: list[GaitPoint], ks) -> tuple[list[int], list[GaitRuns]]:
    """Worker task: the runs of gaits[k] for k in ks (kernels on one thread meanwhile)."""
    ks = [int(k) for k in ks]
    return ks, [predict_gait(inputs, gaits[k]) for k in ks]


def build_gait_map(inputs: PlanInputs, gaits: list[GaitPoint], *, workers: int | None = None,
                   scheduler: str | None = None, progress: bool = False,
                   command: str = '', scheduler_timeout_s: float = 10.0) -> GaitMap:
    """Predict every gait over the spread (maps/build.py's executors: this process and
    workers - 1 worker processes, or a Dask scheduler) and hold the runs in a GaitMap."""
    from tqdm import tqdm

    from .. import __version__
    from ..maps.build import (
        _run_dask,
        _run_inline,
        chunk_indices,
        default_workers,
        local_workers,
        probe_scheduler,
    )
    if not gaits:
        raise ValueError('a gait map needs at least one gait')
    inputs.multibody()                         # a bad robot fails here, before any worker
    if scheduler:
        probe_scheduler(scheduler)
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f'workers must be >= 1, got {workers}')
    results: dict[int, GaitRuns] = {}
    with ExitStack() as stack:
        local = (stack.enter_context(local_workers(min(workers, len(gaits))))
                 if workers > 1 and not scheduler and len(gaits) > 1 else None)
        # one gait per chunk: a gait costs from a second to minutes, so small chunks balance
        chunks = chunk_indices(len(gaits), len(gaits), per_worker=1)
        it: Iterator
        if scheduler:
            it = _run_dask(inputs, gaits, chunks, scheduler, scheduler_timeout_s, _solve)
        elif local is None:
            it = _run_inline(inputs, gaits, chunks, _solve)
        else:
            it = local.run(inputs, gaits, chunks, _solve)
        with tqdm(total=len(gaits), unit='gait', file=sys.stderr, disable=not progress,
                  desc=f'gait map {inputs.multibody().name}/{inputs.medium.name}',
                  dynamic_ncols=True) as bar:
            for ks, rs in it:
                results.update(zip(ks, rs))
                bar.update(len(ks))
    ordered = [results[k] for k in range(len(gaits))]
    attrs = {'robot': inputs.multibody().name, 'medium': inputs.medium.name,
             'inputs_sha256': inputs.inputs_sha256(),
             'inputs_json': json.dumps(inputs.identity(), sort_keys=True, default=str),
             'package_version': __version__, 'build_command': command,
             'build_time_utc': datetime.now(UTC).isoformat(timespec='seconds')}
    return GaitMap(attrs, _arrays(gaits, ordered, inputs.phis))


def _arrays(gaits: list[GaitPoint], runs: list[GaitRuns], phis) -> dict:
    first = runs[0]
    return {
        'gaits': np.array([g.as_array() for g in gaits], dtype=np.float64),
        'gait_names': np.array([g.name for g in gaits], dtype=object),
        'runnable': np.array([r.runnable or '' for r in runs], dtype=object),
        'phi': np.array(phis, dtype=np.float64),
        'run_labels': np.array(first.labels, dtype=object),
        'pairs': np.array(first.pairs, dtype=np.int64).reshape(-1, 2),
        'status': np.array([r.status for r in runs], dtype=object),
        'reason': np.array([r.reason for r in runs], dtype=object),
        'pose': np.array([r.pose for r in runs], dtype=np.float64),
        'energy_elec_J': np.array([r.energy_elec_J for r in runs], dtype=np.float64),
        'capacity_N': np.array([r.capacity_N for r in runs], dtype=np.float64),
        'cap_reason': np.array([r.cap_reason for r in runs], dtype=object),
        'steps': np.array([r.steps for r in runs], dtype=np.int64),
    }


# ---------------------------------------------------------------------- files
def content_sha256(attrs: dict, arrays: dict) -> str:
    """SHA-256 of everything that defines the answers: ANSWER_ATTRS and every array, each fed
    as one length-framed item (maps.hdf5.ContentHash; numbers as little-endian float64 or
    int64, strings UTF-8 joined by NUL)."""
    h = ContentHash(b'rftgls.gait_map/1\0')
    for key in ANSWER_ATTRS:
        h.feed(key, str(attrs[key]).encode())
    for name in NUMBER_SETS:
        a = np.asarray(arrays[name])
        h.array(name, a, '<f8' if a.dtype.kind == 'f' else '<i8')
    for name in STRING_SETS:
        a = np.asarray(arrays[name])
        h.feed(name, f'{a.shape}'.encode() + b'\0'
               + '\0'.join(str(s) for s in a.reshape(-1)).encode())
    return h.hexdigest()


def save(path: str | Path, gmap: GaitMap) -> Path:
    """Write the map atomically (safe_write) with its content hash."""
    path = Path(path)
    digest = content_sha256(gmap.attrs, gmap.arrays)
    comp = {'compression': 'gzip', 'compression_opts': 4, 'shuffle': True, 'track_times': False}
    with atomic_write(path) as tmp, h5py.File(tmp, 'w', track_order=True) as f:
        f.attrs['schema'] = SCHEMA
        f.attrs['schema_version'] = SCHEMA_VERSION
        for key in ANSWER_ATTRS + INFO_ATTRS + VOLATILE_ATTRS:
            f.attrs[key] = gmap.attrs[key]
        f.attrs[HASH_ATTR] = digest
        for name in NUMBER_SETS:
            f.create_dataset(name, data=gmap.arrays[name], **comp)
        for name in STRING_SETS:
            f.create_dataset(name, data=np.asarray(gmap.arrays[name], dtype=object),
                             dtype=h5py.string_dtype(), track_times=False)
    return path


def load(path: str | Path, expected_sha256: str | None = None) -> GaitMap:
    """Read and verify a gait map; MapFileError (one line naming the file) on any problem."""
    path = regular_map_file(path)
    if expected_sha256 is None and path.parent.resolve() == maps_dir().resolve():
        expected_sha256 = SHIPPED_SHA256.get(path.name)
    try:
        with h5py.File(path, 'r') as f:
            gmap = _read(f)
    except MapFileError as exc:
        raise MapFileError(f'{path}: {exc}') from None
    except (OSError, KeyError, TypeError, ValueError, RuntimeError) as exc:
        msg = ' '.join(str(exc).split()) or type(exc).__name__
        raise MapFileError(f'{path}: unreadable or corrupt gait map ({msg})') from None
    digest = content_sha256(gmap.attrs, gmap.arrays)
    if digest != gmap.attrs.get(HASH_ATTR):
        raise MapFileError(f'{path}: content hash {digest[:12]}... does not match its '
                           f'{HASH_ATTR}: the file was changed after it was written')
    if expected_sha256 is not None and digest != expected_sha256:
        raise MapFileError(f'{path}: content hash {digest[:12]}... does not match the hash '
                           f'recorded for this shipped gait map ({expected_sha256[:12]}...)')
    return gmap


def _read(f: h5py.File) -> GaitMap:
    if f.attrs.get('schema') != SCHEMA:
        raise MapFileError(f'not a gait map (schema {f.attrs.get("schema")!r})')
    if int(f.attrs.get('schema_version', -1)) != SCHEMA_VERSION:
        raise MapFileError(f'gait map schema version {f.attrs.get("schema_version")!r}; this '
                           f'reader handles {SCHEMA_VERSION}')
    attrs = {}
    for key in ANSWER_ATTRS + INFO_ATTRS + VOLATILE_ATTRS + (HASH_ATTR,):
        if key not in f.attrs:
            raise MapFileError(f'attribute {key} is missing')
        v = f.attrs[key]
        attrs[key] = v.decode() if isinstance(v, bytes) else str(v)
    arrays = {}
    for name in NUMBER_SETS + STRING_SETS:
        if name not in f or not isinstance(f[name], h5py.Dataset):
            raise MapFileError(f'dataset /{name} is missing')
        check_dataset_size(f[name])
        a = f[name][()]
        if name in STRING_SETS:
            a = np.vectorize(lambda s: s.decode() if isinstance(s, bytes) else str(s),
                             otypes=[object])(a) if a.size else a.astype(object)
        arrays[name] = a
    n, r = len(arrays['gaits']), len(arrays['run_labels'])
    k = len(arrays['phi'])
    want = {'gaits': (n, 5), 'gait_names': (n,), 'runnable': (n,), 'status': (n, r),
            'reason': (n, r), 'pose': (n, r, 4), 'energy_elec_J': (n, r),
            'capacity_N': (n, r, k), 'cap_reason': (n, r, k), 'steps': (n, r)}
    for name, shape in want.items():
        if arrays[name].shape != shape:
            raise MapFileError(f'dataset /{name} has shape {arrays[name].shape}, expected '
                               f'{shape}')
    if arrays['pairs'].ndim != 2 or arrays['pairs'].shape[1] != 2 or (
            arrays['pairs'].size and (arrays['pairs'].min() < 0 or arrays['pairs'].max() >= r)):
        raise MapFileError('dataset /pairs does not index the runs')
    return GaitMap(attrs, arrays)


def shipped_paths(robot: str) -> list[Path]:
    """The shipped gait maps of a robot preset that are installed."""
    return [maps_dir() / n for n in SHIPPED.get(robot, ()) if (maps_dir() / n).is_file()]


# A gait map answers for a sled within this of its own mass, kg (sleds are weighed to grams).
SLED_MATCH_KG = 0.005


def for_sled(sled_kg: float, paths: Iterable[Path]) -> tuple[GaitMap | None, list[float]]:
    """The first gait map of ``paths`` built for this sled (kg, within SLED_MATCH_KG), and the
    sled masses (kg) of the maps read before it (all of them when none matches)."""
    seen: list[float] = []
    for p in paths:
        gmap = load(p)
        kg = float(json.loads(str(gmap.attrs['inputs_json']))['sled_kg'])
        if abs(kg - sled_kg) <= SLED_MATCH_KG:
            return gmap, seen
        seen.append(kg)
    return None, seen
