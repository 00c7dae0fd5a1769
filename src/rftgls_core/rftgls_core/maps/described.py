"""Capacity maps over the state variables an anchor description declares.

The robot maps (grid.py, hdf5.py, query.py) have four fixed state axes (h, theta_b, theta_l1,
theta_l2). A description (description.py) declares its own state variables, with names, units
and default map ranges; maps over exactly those are built by described_build.py and stored
and queried here:

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

Answers come from posed.PosedAnchorSolver at phi with yaw 0 (the sagittal reduction when the
description claims the symmetry, which is checked at every node; else auto), so the twists are
6D world twists at the tether point. Query (`DescribedMap.query`): multilinear over the state
axes and phi, the conservative cell rule of query.py (any weighted corner without a value
withholds the value, reported with the most conservative corner status) with its support-edge
rules that need no stored margin (valued-corner, opt-in zeros; DescribedMap), OUT_OF_RANGE off
the grid; and a query that names a different description identity is refused
(INVALID_INPUT, 'description_mismatch'): a map answers only for the anchor it was built for.
"""
from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from ..posed import PosedAnchorResult
from ..rft.media import Medium
from ..types import Status
from .errors import MapFileError
from .grid import DEFAULT_PHI_DEG, GridShape, check_axis, check_pulls
from .hdf5 import STATUS_NAMES, ContentHash, NodeAnswers, read_dataset
from .interpolate import locate
from .shipped import regular_map_file

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
class DescribedMapData(NodeAnswers):
    """A described map's node answers (maps/hdf5.py NodeAnswers) over a DescribedGrid."""

    grid: DescribedGrid


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
    from rftgls_conventions.safe_write import atomic_write
    path = Path(path)
    comp = {'compression': 'gzip', 'compression_opts': 4, 'shuffle': True, 'track_times': False}
    with atomic_write(path) as tmp, h5py.File(tmp, 'w', track_order=True) as f:
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
        with h5py.File(regular_map_file(path), 'r') as f:
            return str(f.attrs.get('schema', '')) == SCHEMA
    except (OSError, MapFileError):
        return False


def load_described_map(path: str | Path) -> DescribedMapData:
    """Read and check a described map (MapFileError, one line, on any problem)."""
    path = regular_map_file(path)
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
            grid = DescribedGrid(names, units, tuple(read_dataset(f['axes'][n]) for n in names),
                                 read_dataset(f['axes/phi']),
                                 tuple(str(p) for p in f['axes/pull'].asstr()[()]))
            arrays = {n: read_dataset(f[n]) for n in ('capacity_N', 'slip_twist_scaled',
                                                      'slip_twist', 'status', 'reason')}
            if list(f['status'].attrs['status_names']) != list(STATUS_NAMES):
                raise MapFileError(f'{path}: status table differs from this reader\'s')
            reason_names = tuple(str(x) for x in f['reason'].attrs['reason_names'])
    except (OSError, KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:
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
    poses (AnchorDescription.sha256) and refuses another one.

    Support-edge rules, those of the robot maps (query.py) that need no stored margin: a cell
    whose valueless weighted corners are all `unsupported` answers the blend of its valued
    corners, renormalised, when they carry >= edge_min_weight of the weight (flag
    'edge_valued'; the robot maps' measured threshold, query.EDGE_MIN_WEIGHT); with
    support_edge=True (opt-in) such a cell counts its unsupported corners as 0 N (flag
    'support_edge'). The robot maps' edge-margin rule needs per-node support margins, which
    a described map does not store: such cells withhold the value."""

    def __init__(self, data: DescribedMapData, source: str = '', support_edge: bool = False,
                 edge_min_weight: float | None = None) -> None:
        from .query import EDGE_MIN_WEIGHT
        self.data = data
        self.source = source
        self._axes = [list(map(float, a)) for a in data.grid.axes] + \
            [list(map(float, data.grid.phi))]
        self.support_edge = bool(support_edge)
        w = EDGE_MIN_WEIGHT if edge_min_weight is None else float(edge_min_weight)
        if not (math.isfinite(w) and w > 0.0):
            raise ValueError(f'edge_min_weight must be a positive share, got {w}')
        self.edge_min_weight = w

    @classmethod
    def load(cls, path: str | Path, support_edge: bool = False) -> 'DescribedMap':
        return cls(load_described_map(path), source=str(path), support_edge=support_edge)

    def _edge(self, only_unsupported: bool, w_valued: float) -> str:
        """The support-edge rule that answers a cell with valueless corners ('' = none)."""
        if not (only_unsupported and w_valued > 0.0):
            return ''
        if w_valued >= self.edge_min_weight - 1e-12:
            return 'edge_valued'
        return 'support_edge' if self.support_edge else ''

    @property
    def grid(self) -> DescribedGrid:
        return self.data.grid

    @property
    def description_sha256(self) -> str:
        return str(self.data.attrs['description_sha256'])

    @property
    def medium_name(self) -> str:
        return str(self.data.attrs['medium'])

    def _fail(self, status: Status, reason: str, detail: str) -> PosedAnchorResult:
        return PosedAnchorResult(status, METHOD, str(self.data.attrs['space']), reason=reason,
                                 detail=detail)

    def query(self, values: Mapping[str, float], phi: float, pull: str,
              description_sha256: str) -> PosedAnchorResult:
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
        c, tw, worst, w_valued, n_bad, only_unsupported = 0.0, np.zeros(6), None, 0.0, 0, True
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
                only_unsupported &= st is Status.UNSUPPORTED
                n_bad += 1
                continue
            w_valued += w
            c += w * float(self.data.capacity_N[idx])
            tw += w * self.data.slip_twist_scaled[idx].astype(float)
        flags: tuple[str, ...] = ()
        edge_detail = ''
        if worst is not None:
            rule = self._edge(only_unsupported, w_valued)
            if not rule:
                st = _BAD_PRIORITY[worst] if worst < len(_BAD_PRIORITY) else Status.INVALID_INPUT
                return self._fail(st, f'cell_{st.value}',
                                  'a weighted cell corner has no value')
            flags = (rule,)
            if rule == 'edge_valued':
                c, tw = c / w_valued, tw / w_valued
                edge_detail = (f'; support edge: blend of the valued corners (weight '
                               f'{w_valued:.3f} >= {self.edge_min_weight:g}), {n_bad} '
                               'unsupported corners left out')
            else:
                edge_detail = (f'; support edge: {n_bad} unsupported corners counted as 0 N '
                               f'(valued weight {w_valued:.3f})')
        norm = float(np.linalg.norm(tw))
        if norm < 1e-9:
            return self._fail(Status.DEGENERATE, 'twist_cancels',
                              'the corner slip twists cancel exactly')
        ts = tw / norm
        # Raw direction: (v, w L_c) -> (v, w), renormalised (the force scale cancels).
        raw = ts / np.r_[np.ones(3), np.full(3, float(self.data.attrs['char_length_m']))]
        raw /= np.linalg.norm(raw)
        return PosedAnchorResult(Status.OK, METHOD, str(self.data.attrs['space']),
                                 capacity_N=max(c, 0.0),
                                 slip_twist=tuple(float(x) for x in raw),
                                 slip_twist_scaled=tuple(float(x) for x in ts),
                                 detail=f'twist_confidence={norm:.3f}' + edge_detail, flags=flags)

    def query_batch(self, values: np.ndarray, phi: float, pull: str,
                    description_sha256: str) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised `query` for slices and plots: values (M, n) SI in the grid's state
        order -> (capacity_N (M,) with NaN where no value, status codes (M,) uint8 of
        STATUS_NAMES). The same cell rule as `query` (a weighted corner without a value
        withholds the value, with the most conservative corner status; OUT_OF_RANGE off the
        grid); twists are not interpolated here (use `query` for them)."""
        from .interpolate import locate_many
        g = self.grid
        values = np.atleast_2d(np.asarray(values, dtype=float))
        M = len(values)
        if description_sha256 != self.description_sha256:
            raise ValueError(f'{self.source or "map"}: built for description '
                             f'{self.description_sha256[:12]}, not {description_sha256[:12]}')
        if pull not in g.pulls:
            raise ValueError(f'pull {pull!r} not in this map (has {", ".join(g.pulls)})')
        if values.shape[1] != len(g.names):
            raise ValueError(f'values need {len(g.names)} columns ({", ".join(g.names)})')
        cols = [values[:, d] for d in range(len(g.names))] + [np.full(M, float(phi))]
        axes = list(g.axes) + [g.phi]
        located = [locate_many(ax, x) for ax, x in zip(axes, cols)]
        p = g.pulls.index(pull)
        status, cap = self.data.status[p], self.data.capacity_N[p].astype(float)
        valued = np.array([Status(n).has_value for n in STATUS_NAMES])
        rank = np.array([_BAD_PRIORITY.index(Status(n)) if Status(n) in _BAD_PRIORITY
                         else len(_BAD_PRIORITY) for n in STATUS_NAMES])
        c = np.zeros(M)
        worst = np.full(M, len(_BAD_PRIORITY) + 1)
        w_valued = np.zeros(M)
        only_unsupported = np.ones(M, dtype=bool)
        unsupported_code = STATUS_NAMES.index(Status.UNSUPPORTED.value)
        for bits in itertools.product((0, 1), repeat=len(axes)):
            w = np.ones(M)
            idx = []
            for (i, t, _), b in zip(located, bits):
                w = w * (t if b else 1.0 - t)
                idx.append(i + b)
            st = status[tuple(idx)]
            weighted = w > 0.0
            has = valued[st]
            c += np.where(weighted & has, w * np.nan_to_num(cap[tuple(idx)]), 0.0)
            w_valued += np.where(weighted & has, w, 0.0)
            worst = np.where(weighted & ~has, np.minimum(worst, rank[st]), worst)
            only_unsupported &= ~(weighted & ~has) | (st == unsupported_code)
        code = np.full(M, STATUS_NAMES.index(Status.OK.value), dtype=np.uint8)
        bad = worst <= len(_BAD_PRIORITY)
        # the support-edge rules (see the class doc), as `query` applies them
        edge = bad & only_unsupported & (w_valued > 0.0)
        valued_rule = edge & (w_valued >= self.edge_min_weight - 1e-12)
        c = np.where(valued_rule, c / np.where(valued_rule, w_valued, 1.0), c)
        bad &= ~(valued_rule | (edge & self.support_edge))
        prio = [STATUS_NAMES.index(s.value) for s in _BAD_PRIORITY] + \
            [STATUS_NAMES.index(Status.INVALID_INPUT.value)]
        code[bad] = np.asarray(prio)[worst[bad]]
        off = np.zeros(M, dtype=bool)
        for _, _, side in located:
            off |= side != 0
        code[off] = STATUS_NAMES.index(Status.OUT_OF_RANGE.value)
        ok = code == STATUS_NAMES.index(Status.OK.value)
        return np.where(ok, np.maximum(c, 0.0), np.nan), code


# ------------------------------------------------------- provenance and identity
def map_medium(data: DescribedMapData) -> Medium:
    """The medium a described map was built with (its provenance)."""
    return Medium(**json.loads(str(data.attrs['provenance_json']))['medium'])


def check_identity(cmap: DescribedMap, desc) -> None:
    """ValueError (one line) unless desc is the description the map was built for."""
    if desc.sha256 != cmap.description_sha256:
        raise ValueError(f'{cmap.source or "map"} was built for description '
                         f'{cmap.data.attrs.get("description_name", "")} '
                         f'({cmap.description_sha256[:12]}); {desc.source} is '
                         f'{desc.sha256[:12]}')
