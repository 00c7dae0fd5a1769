"""Capacity-map files: the HDF5 schema, `save_map` and `load_map` (with validation).

Schema `rftgls.capacity_map`, version 1 (SCHEMA_VERSION). P = number of pull orientations,
(Nh, Nb, N1, N2) = state axes, K = pull angles. Everything is SI.

    /                          root attributes
        schema                 'rftgls.capacity_map'
        schema_version         int, 1
        robot, medium          preset names
        method, rft_model      limit-surface method, RFT stress model name
        n_twists               twists sampled per state
        scaling_force_N        s_F of the scaled metric (N)
        scaling_length_m       L_c of the scaled metric (m)
        package_version        rftgls_core.__version__ of the builder
        build_command          command line (or call) that built the file
        provenance_json        JSON (sorted keys) of AnchorModel.describe(): robot and medium
                               parameters, RFT model, method, n_twists, scaling
        build_time_utc         ISO time of the build; the ONLY attribute that differs between
                               two builds from the same inputs (VOLATILE_ATTRS)
    /axes/h                    (Nh,) float64, attrs units='m', human_unit='mm', human_values
    /axes/theta_b              (Nb,) float64, rad (human: deg)
    /axes/theta_l1             (N1,) float64, rad (human: deg)
    /axes/theta_l2             (N2,) float64, rad (human: deg)
    /axes/phi                  (K,)  float64, rad (human: deg); tether angle, types.pull_direction
    /axes/pull                 (P,)  UTF-8 strings, 'forward' / 'backward'
    /capacity_N                (P, Nh, Nb, N1, N2, K) float32, N; NaN where status has no value
    /slip_twist_scaled         (P, Nh, Nb, N1, N2, K, 3) float32, unit vector of the scaled
                               metric (vx, vz, wy L_c) / norm; NaN where status has no value
    /slip_twist                (P, Nh, Nb, N1, N2, K, 3) float32, the raw (vx, vz, wy) unit
                               direction (surfaces.scaling.Scaling.twist_from_scaled)
    /status                    (P, Nh, Nb, N1, N2, K) uint8; attr status_names: code -> name
                               (types.Status values)
    /reason                    (P, Nh, Nb, N1, N2, K) uint8; attr reason_names: code -> reason
                               string of CapacityResult ('' = none), sorted

Axes are strictly increasing, finite, with >= 2 nodes. Every axis and value array must exist
with exactly these shapes and dtype kinds; a file that fails any check raises MapFileError with
one line naming the file and the problem. Data arrays are gzip-compressed (shuffle, level 4);
compression is deterministic, so two builds differ only in build_time_utc.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ..types import Status
from .grid import AXIS_HUMAN, AXIS_UNITS, STATE_AXES, MapGrid, check_axis

SCHEMA = 'rftgls.capacity_map'
SCHEMA_VERSION = 1
STATUS_NAMES = tuple(s.value for s in Status)          # code -> name written by this version
VOLATILE_ATTRS = ('build_time_utc',)
REQUIRED_ATTRS = ('schema', 'schema_version', 'robot', 'medium', 'method', 'rft_model',
                  'n_twists', 'scaling_force_N', 'scaling_length_m', 'package_version',
                  'build_command', 'provenance_json')
AXES = STATE_AXES + ('phi',)


class MapFileError(ValueError):
    """A map file that cannot be used: unreadable, truncated, wrong schema, inconsistent."""


@dataclass(eq=False)
class MapData:
    """Everything a map file holds, in memory. Arrays are shaped like `grid.shape` (+ (3,)).

    status: uint8 codes into STATUS_NAMES. reason: uint8 codes into reason_names.
    attrs: the root attributes other than schema/schema_version (strings and numbers).
    """

    grid: MapGrid
    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    reason_names: tuple[str, ...]
    attrs: dict = field(default_factory=dict)

    @property
    def provenance(self) -> dict:
        """The parsed provenance_json plus the scalar root attributes."""
        prov = json.loads(self.attrs.get('provenance_json', '{}'))
        for key, value in self.attrs.items():
            if key != 'provenance_json':
                prov.setdefault(key, value)
        return prov

    def statuses(self) -> np.ndarray:
        """The status array as an object array of Status (for reports, not hot paths)."""
        table = np.array([Status(n) for n in STATUS_NAMES], dtype=object)
        return table[self.status]


def _write_axis(group: h5py.Group, name: str, values: np.ndarray) -> None:
    ds = group.create_dataset(name, data=np.asarray(values, dtype=np.float64), track_times=False)
    unit, factor = AXIS_HUMAN[name]
    ds.attrs['units'] = AXIS_UNITS[name]
    ds.attrs['human_unit'] = unit
    # Rounded for reading only: the SI values above are the truth.
    ds.attrs['human_values'] = np.round(values * factor, 9)


def save_map(path: str | Path, data: MapData) -> Path:
    """Write `data` to `path` (overwrites) following the schema above; returns the path."""
    path = Path(path)
    g = data.grid
    shape = g.shape
    checks = {'capacity_N': shape, 'status': shape, 'reason': shape,
              'slip_twist_scaled': shape + (3,), 'slip_twist': shape + (3,)}
    for name, want in checks.items():
        if getattr(data, name).shape != want:
            raise ValueError(f'{name} has shape {getattr(data, name).shape}, grid needs {want}')
    missing = [a for a in REQUIRED_ATTRS[2:] if a not in data.attrs]
    if missing:
        raise ValueError(f'map attributes missing: {", ".join(missing)}')
    comp = {'compression': 'gzip', 'compression_opts': 4, 'shuffle': True, 'track_times': False}
    with h5py.File(path, 'w', track_order=True) as f:
        f.attrs['schema'] = SCHEMA
        f.attrs['schema_version'] = SCHEMA_VERSION
        for key in REQUIRED_ATTRS[2:] + VOLATILE_ATTRS:
            if key in data.attrs:
                f.attrs[key] = data.attrs[key]
        axes = f.create_group('axes', track_order=True)
        for name in AXES:
            _write_axis(axes, name, getattr(g, name))
        axes.create_dataset('pull', data=np.array(g.pulls, dtype=object),
                            dtype=h5py.string_dtype(), track_times=False)
        f.create_dataset('capacity_N', data=data.capacity_N.astype(np.float32), **comp)
        f.create_dataset('slip_twist_scaled', data=data.slip_twist_scaled.astype(np.float32),
                         **comp)
        f.create_dataset('slip_twist', data=data.slip_twist.astype(np.float32), **comp)
        st = f.create_dataset('status', data=data.status.astype(np.uint8), **comp)
        st.attrs['status_names'] = list(STATUS_NAMES)
        rs = f.create_dataset('reason', data=data.reason.astype(np.uint8), **comp)
        rs.attrs['reason_names'] = list(data.reason_names) if data.reason_names else ['']
    return path


def _attr(value):
    """h5py attribute -> plain Python (str, int, float, list)."""
    if isinstance(value, bytes):
        return value.decode('utf-8')
    if isinstance(value, np.ndarray):
        return [_attr(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _dataset(f: h5py.File, name: str, shape: tuple, kind: str) -> np.ndarray:
    if name not in f or not isinstance(f[name], h5py.Dataset):
        raise MapFileError(f'dataset /{name} is missing')
    ds = f[name]
    if ds.shape != shape:
        raise MapFileError(f'dataset /{name} has shape {ds.shape}, the axes need {shape}')
    if ds.dtype.kind not in kind:
        raise MapFileError(f'dataset /{name} has dtype {ds.dtype}, expected kind {kind!r}')
    return ds[()]


def _read(f: h5py.File) -> MapData:
    schema = _attr(f.attrs.get('schema'))
    if schema != SCHEMA:
        raise MapFileError(f'not a capacity map (schema attribute {schema!r}, '
                           f'expected {SCHEMA!r})')
    version = _attr(f.attrs.get('schema_version'))
    if not isinstance(version, int) or isinstance(version, bool):
        raise MapFileError(f'schema_version {version!r} is not an integer')
    if version != SCHEMA_VERSION:
        newer = ' (newer than this reader)' if version > SCHEMA_VERSION else ''
        raise MapFileError(f'schema version {version}{newer}; this reader handles '
                           f'version {SCHEMA_VERSION}')
    missing = [a for a in REQUIRED_ATTRS if a not in f.attrs]
    if missing:
        raise MapFileError(f'root attributes missing: {", ".join(missing)}')
    attrs = {k: _attr(f.attrs[k]) for k in REQUIRED_ATTRS[2:] + VOLATILE_ATTRS if k in f.attrs}
    for key in ('scaling_force_N', 'scaling_length_m'):
        v = attrs[key]
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise MapFileError(f'attribute {key} must be a positive number, got {v!r}')
    try:
        json.loads(attrs['provenance_json'])
    except (TypeError, ValueError):
        raise MapFileError('attribute provenance_json is not valid JSON') from None

    axes = {}
    for name in AXES:
        key = f'axes/{name}'
        if key not in f or not isinstance(f[key], h5py.Dataset):
            raise MapFileError(f'axis /{key} is missing')
        if f[key].dtype.kind != 'f':
            raise MapFileError(f'axis /{key} has dtype {f[key].dtype}, expected float')
        values = f[key][()]
        if values.ndim != 1:
            raise MapFileError(f'axis /axes/{name} must be 1-D, has shape {values.shape}')
        try:
            axes[name] = check_axis(name, values)
        except ValueError as exc:
            raise MapFileError(str(exc)) from None
    if 'axes/pull' not in f:
        raise MapFileError('dataset /axes/pull is missing')
    try:
        pulls = tuple(str(p) for p in f['axes/pull'].asstr()[()])
        grid = MapGrid(**axes, pulls=pulls)
    except (ValueError, TypeError) as exc:
        raise MapFileError(f'bad /axes/pull: {exc}') from None

    shape = grid.shape
    cap = _dataset(f, 'capacity_N', shape, 'f')
    ts = _dataset(f, 'slip_twist_scaled', shape + (3,), 'f')
    tr = _dataset(f, 'slip_twist', shape + (3,), 'f')
    status = _dataset(f, 'status', shape, 'u')
    reason = _dataset(f, 'reason', shape, 'u')

    names = _attr(f['status'].attrs.get('status_names'))
    if not isinstance(names, list) or not names:
        raise MapFileError('/status has no status_names table')
    known = set(STATUS_NAMES)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise MapFileError(f'/status names unknown statuses: {", ".join(map(str, unknown))}')
    if status.size and int(status.max()) >= len(names):
        raise MapFileError(f'/status code {int(status.max())} is outside its table '
                           f'({len(names)} names)')
    # Re-code to this version's table, so a file written with another order still reads.
    recode = np.array([STATUS_NAMES.index(n) for n in names], dtype=np.uint8)
    status = recode[status]
    reason_names = _attr(f['reason'].attrs.get('reason_names'))
    if not isinstance(reason_names, list) or not reason_names:
        raise MapFileError('/reason has no reason_names table')
    if reason.size and int(reason.max()) >= len(reason_names):
        raise MapFileError(f'/reason code {int(reason.max())} is outside its table')

    valued = np.isin(status, [STATUS_NAMES.index(s.value) for s in Status if s.has_value])
    if not np.all(np.isfinite(cap[valued])) or np.any(cap[valued] < 0):
        raise MapFileError('capacity_N is negative or not finite at a node with a value')
    norms = np.linalg.norm(ts[valued].astype(np.float64), axis=-1)
    if not np.all(np.abs(norms - 1.0) < 1e-3):
        raise MapFileError('slip_twist_scaled is not a unit vector at a node with a value')
    return MapData(grid=grid, capacity_N=cap, slip_twist_scaled=ts, slip_twist=tr,
                   status=status, reason=reason, reason_names=tuple(reason_names), attrs=attrs)


def load_map(path: str | Path) -> MapData:
    """Read and validate a map file. Any problem -> MapFileError('<path>: <one line>')."""
    path = Path(path)
    if not path.is_file():
        raise MapFileError(f'{path}: no such map file')
    try:
        with h5py.File(path, 'r') as f:
            return _read(f)
    except MapFileError as exc:
        raise MapFileError(f'{path}: {exc}') from None
    except (OSError, KeyError, TypeError, ValueError, RuntimeError) as exc:
        # h5py reports truncated/corrupt files and unreadable chunks as OSError/KeyError.
        msg = ' '.join(str(exc).split()) or type(exc).__name__
        raise MapFileError(f'{path}: unreadable or corrupt HDF5 map ({msg})') from None
