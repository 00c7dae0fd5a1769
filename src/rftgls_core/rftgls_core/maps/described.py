"""Capacity maps over the state variables an anchor description declares (issue 12, item 7).

The robot maps (grid.py, hdf5.py, query.py) have four fixed state axes (h, theta_b, theta_l1,
theta_l2). A description (description.py) declares its own state variables, with names, units
and default map ranges; this module builds, stores and queries maps over exactly those:

    /                          schema 'rftgls.described_map', schema_version 1
        description_sha256     identity of the description (description.description_sha256)
        description_name       its `name:`
        char_length_m          L_c of the scaled twists (the description's char_length_m)
        state_names            the state variables in the description's order
        medium, method, rft_model, n_twists, space, provenance_json (medium parameters),
        package_version, build_command, build_time_utc, content_sha256
    /axes/<name>               (N_i,) float64, SI (units 'm' or 'rad'; human_unit the YAML's)
    /axes/phi                  (K,) float64, rad
    /axes/pull                 (P,) strings
    /capacity_N                (P, N_1, ..., N_n, K) float32, N; NaN without value
    /slip_twist_scaled         (..., 6) float32 (vx, vy, vz, wx L_c, wy L_c, wz L_c), unit
    /slip_twist                (..., 6) float32 raw (m/s, rad/s) direction, unit norm
    /status, /reason           (P, N_1, ..., N_n, K) uint8 codes (status_names, reason_names)

Answers come from scene.SceneModel at phi with yaw 0 (the sagittal reduction when the
description claims the symmetry, which is checked at every node; else auto), so the twists are
6D world twists at the tether point. Query (`DescribedMap.query`): multilinear over the state
axes and phi, the conservative cell rule of query.py (any weighted corner without a value
withholds the value, reported with the most conservative corner status), OUT_OF_RANGE off
the grid; and a query that names a different description identity is refused
(INVALID_INPUT, 'description_mismatch'): a map answers only for the anchor it was built for.
"""
from __future__ import annotations

import dataclasses
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import h5py
import numpy as np

from .. import __version__
from ..scene import SceneResult
from ..types import Status
from .errors import MapFileError
from .grid import DEFAULT_PHI_DEG, GridShape, check_axis, check_pulls
from .hdf5 import STATUS_NAMES, ContentHash, empty_answers
from .interpolate import locate

SCHEMA = 'rftgls.described_map'
SCHEMA_VERSION = 1
METHOD = 'map'
ANSWER_ATTRS = ('description_sha256', 'state_names', 'medium', 'method', 'rft_model',
                'n_twists', 'space', 'char_length_m', 'provenance_json')
OTHER_ATTRS = ('description_name', 'package_version', 'build_command', 'build_time_utc')
_BAD_PRIORITY = (Status.UNSUPPORTED, Status.DEGENERATE, Status.INVALID_INPUT, Status.STALE)


@dataclass(frozen=True, eq=False)
class DescribedGrid(GridShape):
    """State axes of a described map (SI, the description's order), phi (rad) and pulls."""

    names: tuple[str, ...]
    units: tuple[str, ...]          # the description's units: 'm' or 'deg'
    axes: tuple[np.ndarray, ...]
    phi: np.ndarray
    pulls: tuple[str, ...]

    def __post_init__(self) -> None:
        if not self.names or len(set(self.names)) != len(self.names) or \
                len(self.names) != len(self.axes) or len(self.units) != len(self.names):
            raise ValueError(f'state axes need distinct names, one axis each: {self.names!r}')
        object.__setattr__(self, 'axes', tuple(check_axis(n, a)
                                               for n, a in zip(self.names, self.axes)))
        object.__setattr__(self, 'phi', check_axis('phi', self.phi))
        check_pulls(self.pulls)

    def values(self, k: int) -> dict[str, float]:
        """State values (SI, by name) of flat C-order state index k."""
        idx = np.unravel_index(int(k), self.state_shape)
        return {n: float(a[i]) for n, a, i in zip(self.names, self.axes, idx)}

    def describe(self) -> str:
        parts = []
        for n, u, a in zip(self.names, self.units, self.axes):
            f = 180.0 / math.pi if u == 'deg' else 1.0
            parts.append(f'{n} {a[0] * f:g}..{a[-1] * f:g} {u} ({len(a)})')
        parts.append(f'phi {math.degrees(self.phi[0]):g}..{math.degrees(self.phi[-1]):g} deg '
                     f'({len(self.phi)})')
        return ', '.join(parts) + f'; pulls {",".join(self.pulls)}; {self.n_states} states'


def description_grid(desc, overrides: Mapping[str, np.ndarray] | None = None,
                     phi_deg=DEFAULT_PHI_DEG, pulls: tuple[str, ...] | None = None
                     ) -> DescribedGrid:
    """The grid of a description: its map ranges, with `overrides` (name -> nodes in the
    description's unit) replacing some; pulls default to the description's pull_scale keys
    (a body without C-legs has one orientation, 'backward')."""
    from ..description import DescriptionError
    overrides = dict(overrides or {})
    unknown = sorted(set(overrides) - set(desc.state_names))
    if unknown:
        raise DescriptionError(f'{desc.source}: no state variable {", ".join(unknown)} (it has '
                               f'{", ".join(desc.state_names)})')
    missing = [v.name for v in desc.state if v.map_range is None and v.name not in overrides]
    if missing:
        raise DescriptionError(f'{desc.source}: state variable(s) {", ".join(missing)} have no '
                               'map range: give `map: [start, stop, count]` in the YAML or '
                               'the nodes on the command line')
    axes = {}
    for v in desc.state:
        if v.name in overrides:
            axes[v.name] = np.array([v.to_si(x) for x in overrides[v.name]])
        else:
            assert v.map_range is not None
            lo, hi, n = v.map_range
            axes[v.name] = np.linspace(lo, hi, n)
    if pulls is None:
        pulls = tuple(p for p in ('forward', 'backward') if p in desc.pull_scale) or ('backward',)
    return DescribedGrid(names=desc.state_names, units=tuple(v.unit for v in desc.state),
                         axes=tuple(axes[n] for n in desc.state_names),
                         phi=np.radians(np.asarray(phi_deg, dtype=float)), pulls=tuple(pulls))


@dataclass(eq=False)
class DescribedMapData:
    grid: DescribedGrid
    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    reason_names: tuple[str, ...]
    attrs: dict = field(default_factory=dict)


def build_described_map(desc, medium, grid: DescribedGrid | None = None, *,
                        method: str = 'direct', model: str = 'agarwal',
                        n_twists: int | None = None, command: str = '',
                        progress: bool = False) -> DescribedMapData:
    """Answers of scene.SceneModel at every node of `grid` (default: the description's map
    ranges), in this process (state order; deterministic). desc: an AnchorDescription;
    medium: a Medium."""
    from tqdm import tqdm

    from ..scene import SceneModel
    grid = description_grid(desc) if grid is None else grid
    if grid.names != desc.state_names:
        raise ValueError(f'grid axes {grid.names} are not the state of {desc.name} '
                         f'{desc.state_names}')
    space = 'sagittal' if desc.symmetry == 'sagittal' else 'auto'
    sm = SceneModel(medium, model=model, method=method, n_twists=n_twists, space=space)
    P, K, S = len(grid.pulls), len(grid.phi), grid.n_states
    cap, ts, tr, status, reasons = empty_answers((P, S, K), 6)
    for k in tqdm(range(S), unit='state', disable=not progress, desc=f'map {desc.name}'):
        values = grid.values(k)
        outside = desc.violations(values)
        for p, pull in enumerate(grid.pulls):
            scene = desc.scene(values, pull) if not outside else None
            for j, phi in enumerate(grid.phi.tolist()):
                if scene is None:   # a map range beyond the physical one: no answer
                    status[p, k, j] = STATUS_NAMES.index(Status.INVALID_INPUT.value)
                    reasons[p, k, j] = 'not_a_pose'
                    continue
                r = sm.predict(scene, phi, 0.0)
                status[p, k, j] = STATUS_NAMES.index(r.status.value)
                reasons[p, k, j] = r.reason
                if r.status.has_value and r.capacity_N is not None:
                    cap[p, k, j] = r.capacity_N
                    ts[p, k, j] = r.slip_twist_scaled
                    tr[p, k, j] = r.slip_twist
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


def content_sha256(data: DescribedMapData) -> str:
    """Hex SHA-256 over what defines the answers (as hdf5.content_sha256 for robot maps)."""
    h = ContentHash(b'rftgls.described_map/content/1\0')
    for key in ANSWER_ATTRS:
        h.feed(f'@{key}', str(data.attrs.get(key, '')).encode())
    g = data.grid
    for n, u, a in zip(g.names, g.units, g.axes):
        h.feed(f'unit/{n}', u.encode())
        h.array(f'axes/{n}', a, '<f8')
    h.array('axes/phi', g.phi, '<f8')
    h.feed('axes/pull', '\n'.join(g.pulls).encode())
    h.answers(data.capacity_N, data.slip_twist_scaled, data.slip_twist, data.status,
              STATUS_NAMES, data.reason, data.reason_names)
    return h.hexdigest()


def save_described_map(path: str | Path, data: DescribedMapData) -> Path:
    path = Path(path)
    comp = {'compression': 'gzip', 'compression_opts': 4, 'shuffle': True, 'track_times': False}
    with h5py.File(path, 'w', track_order=True) as f:
        f.attrs['schema'] = SCHEMA
        f.attrs['schema_version'] = SCHEMA_VERSION
        for key in ANSWER_ATTRS + OTHER_ATTRS:
            f.attrs[key] = data.attrs[key]
        f.attrs['content_sha256'] = content_sha256(data)
        axes = f.create_group('axes', track_order=True)
        for n, u, a in zip(data.grid.names, data.grid.units, data.grid.axes):
            ds = axes.create_dataset(n, data=a, track_times=False)
            ds.attrs['units'] = 'm' if u == 'm' else 'rad'
            ds.attrs['human_unit'] = u
        axes.create_dataset('phi', data=data.grid.phi, track_times=False).attrs['units'] = 'rad'
        axes.create_dataset('pull', data=np.array(data.grid.pulls, dtype=object),
                            dtype=h5py.string_dtype(), track_times=False)
        for name in ('capacity_N', 'slip_twist_scaled', 'slip_twist'):
            f.create_dataset(name, data=getattr(data, name), **comp)
        f.create_dataset('status', data=data.status, **comp).attrs['status_names'] = \
            list(STATUS_NAMES)
        f.create_dataset('reason', data=data.reason, **comp).attrs['reason_names'] = \
            list(data.reason_names)
    return path


def is_described_map(path: str | Path) -> bool:
    try:
        with h5py.File(path, 'r') as f:
            return str(f.attrs.get('schema', '')) == SCHEMA
    except OSError:
        return False


def load_described_map(path: str | Path) -> DescribedMapData:
    """Read and check a described map (MapFileError, one line, on any problem)."""
    path = Path(path)
    try:
        with h5py.File(path, 'r') as f:
            if str(f.attrs.get('schema', '')) != SCHEMA:
                raise MapFileError(f'{path}: not a described map (schema '
                                   f'{f.attrs.get("schema")!r})')
            if int(f.attrs.get('schema_version', -1)) != SCHEMA_VERSION:
                raise MapFileError(f'{path}: schema version {f.attrs.get("schema_version")}, '
                                   f'this reader handles {SCHEMA_VERSION}')
            attrs = {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in f.attrs.items()}
            names = tuple(str(attrs['state_names']).split(','))
            units = tuple(str(f['axes'][n].attrs['human_unit']) for n in names)
            grid = DescribedGrid(names, units, tuple(f['axes'][n][()] for n in names),
                                 f['axes/phi'][()],
                                 tuple(str(p) for p in f['axes/pull'].asstr()[()]))
            arrays = {n: f[n][()] for n in ('capacity_N', 'slip_twist_scaled', 'slip_twist',
                                            'status', 'reason')}
            if list(f['status'].attrs['status_names']) != list(STATUS_NAMES):
                raise MapFileError(f'{path}: status table differs from this reader\'s')
            reason_names = tuple(str(x) for x in f['reason'].attrs['reason_names'])
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, MapFileError):
            raise
        raise MapFileError(f'{path}: bad described map ({" ".join(str(exc).split())})') \
            from None
    data = DescribedMapData(grid, reason_names=reason_names, attrs=attrs, **arrays)
    for name in ('capacity_N', 'status', 'reason'):
        if getattr(data, name).shape != grid.shape:
            raise MapFileError(f'{path}: /{name} has shape {getattr(data, name).shape}, the '
                               f'axes need {grid.shape}')
    if content_sha256(data) != attrs.get('content_sha256'):
        raise MapFileError(f'{path}: content does not match its content_sha256 (changed '
                           'after it was written)')
    return data


class DescribedMap:
    """Queries of a described map. `query` needs the identity of the description the caller
    poses (AnchorDescription.sha256) and refuses another one."""

    def __init__(self, data: DescribedMapData, source: str = '') -> None:
        self.data = data
        self.source = source
        self._axes = [list(map(float, a)) for a in data.grid.axes] + \
            [list(map(float, data.grid.phi))]

    @classmethod
    def load(cls, path: str | Path) -> 'DescribedMap':
        return cls(load_described_map(path), source=str(path))

    @property
    def grid(self) -> DescribedGrid:
        return self.data.grid

    @property
    def description_sha256(self) -> str:
        return str(self.data.attrs['description_sha256'])

    @property
    def medium_name(self) -> str:
        return str(self.data.attrs['medium'])

    def _fail(self, status: Status, reason: str, detail: str) -> SceneResult:
        return SceneResult(status, METHOD, str(self.data.attrs['space']), reason=reason,
                           detail=detail)

    def query(self, values: Mapping[str, float], phi: float, pull: str,
              description_sha256: str) -> SceneResult:
        """Capacity (N) and 6D slip twist at state `values` (SI, by name), tether angle phi
        (rad), pull orientation; description_sha256: identity of the caller's description."""
        if description_sha256 != self.description_sha256:
            return self._fail(Status.INVALID_INPUT, 'description_mismatch',
                              f'map built for description {self.description_sha256[:12]} '
                              f'({self.data.attrs.get("description_name", "")}), asked for '
                              f'{str(description_sha256)[:12]}')
        g = self.grid
        if pull not in g.pulls:
            return self._fail(Status.INVALID_INPUT, 'pull_not_in_map',
                              f'pull {pull!r} not in this map (has {", ".join(g.pulls)})')
        missing = [n for n in g.names if n not in values]
        if missing:
            return self._fail(Status.INVALID_INPUT, 'invalid_state',
                              f'no value for {", ".join(missing)}')
        coords = [float(values[n]) for n in g.names] + [float(phi)]
        if not all(map(math.isfinite, coords)):
            return self._fail(Status.INVALID_INPUT, 'invalid_state',
                              f'state and phi must be finite, got {coords}')
        cells = [locate(ax, x) for ax, x in zip(self._axes, coords)]
        out = [n for n, (_, _, side) in zip(g.names + ('phi',), cells) if side]
        if out:
            return self._fail(Status.OUT_OF_RANGE, 'out_of_grid',
                              f'{", ".join(out)} outside the grid')
        p = g.pulls.index(pull)
        c, tw, worst = 0.0, np.zeros(6), None
        for bits in itertools.product((0, 1), repeat=len(cells)):
            w = 1.0
            for (_, t, _), b in zip(cells, bits):
                w *= t if b else 1.0 - t
            if w == 0.0:
                continue   # before indexing: zero-weight corners may lie past the axis end
            idx = (p,) + tuple(i + b for (i, _, _), b in zip(cells, bits))
            st = Status(STATUS_NAMES[int(self.data.status[idx])])
            if not st.has_value:
                rank = _BAD_PRIORITY.index(st) if st in _BAD_PRIORITY else len(_BAD_PRIORITY)
                worst = rank if worst is None else min(worst, rank)
                continue
            c += w * float(self.data.capacity_N[idx])
            tw += w * self.data.slip_twist_scaled[idx].astype(float)
        if worst is not None:
            st = _BAD_PRIORITY[worst] if worst < len(_BAD_PRIORITY) else Status.INVALID_INPUT
            return self._fail(st, f'cell_{st.value}',
                              'a weighted cell corner has no value')
        norm = float(np.linalg.norm(tw))
        if norm < 1e-9:
            return self._fail(Status.DEGENERATE, 'twist_cancels',
                              'the corner slip twists cancel exactly')
        ts = tw / norm
        # Raw direction: (v, w L_c) -> (v, w), renormalised (the force scale cancels).
        raw = ts / np.r_[np.ones(3), np.full(3, float(self.data.attrs['char_length_m']))]
        raw /= np.linalg.norm(raw)
        return SceneResult(Status.OK, METHOD, str(self.data.attrs['space']),
                           capacity_N=max(c, 0.0),
                           slip_twist=tuple(float(x) for x in raw),
                           slip_twist_scaled=tuple(float(x) for x in ts),
                           detail=f'twist_confidence={norm:.3f}')
