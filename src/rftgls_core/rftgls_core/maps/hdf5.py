"""Capacity-map files: the HDF5 schema, `save_map` and `load_map` (with validation).

Schema `rftgls.capacity_map`, version 2 (SCHEMA_VERSION; version 1 files, without the two
support-margin datasets, still load, with the edge-margin rule off). P = number of pull
orientations, (Nh, Nb, N1, N2) = state axes, K = pull angles. Everything is SI.

    /                          root attributes
        schema                 'rftgls.capacity_map'
        schema_version         int, 2 (1: no /support_margin*)
        robot, medium          preset names
        method, rft_model      limit-surface method, RFT stress model name
        n_twists               twists sampled per state
        scaling_force_N        s_F of the scaled metric (N)
        scaling_length_m       L_c of the scaled metric (m)
        package_version        rftgls_core.__version__ of the builder
        build_command          command line (or call) that built the file
        provenance_json        JSON (sorted keys) of RobotPredictor.describe(): robot and medium
                               parameters, RFT model, method, n_twists, scaling
        build_time_utc         ISO time of the build; the ONLY attribute that differs between
                               two builds from the same inputs (VOLATILE_ATTRS)
        content_sha256         hex SHA-256 of everything that defines the answers
                               (content_sha256(): ANSWER_ATTRS, every axis, the pull labels, the
                               value arrays, status and reason codes and their name tables);
                               written by save_map, checked by load_map
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
    /support_margin            (P, Nh, Nb, N1, N2) float32, scaled metric: distance of the
                               origin from the sampled limit surface, >= 0 where the weight is
                               held, <= 0 where not, NaN without a surface (edge.py)
    /support_margin_grad       (P, Nh, Nb, N1, N2, 4) float32, its gradient along (h, theta_b,
                               theta_l1, theta_l2) in 1/m and 1/rad, at the corners of cells
                               whose nodes disagree on support (NaN elsewhere, or where a
                               sample has no surface)

Axes are strictly increasing, finite, with >= 2 nodes. Every axis and value array must exist
with exactly these shapes and dtype kinds; a file that fails any check raises MapFileError with
one line naming the file and the problem. Data arrays are gzip-compressed (shuffle, level 4);
compression is deterministic, so two builds differ only in build_time_utc.

Integrity (docs/design/map-integrity.md): the shape checks above cannot see a capacity doubled
or two pull labels swapped, so load_map recomputes content_sha256 and refuses a mismatch; a
shipped map (a SHIPPED file in maps_dir()) must also match the hash recorded in the package
(shipped.SHIPPED_SHA256), so re-hashing a tampered file does not help. A file without the
attribute (a user map written before it existed) loads with a MapIntegrityWarning.
"""
from __future__ import annotations

import hashlib
import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from rftgls_conventions.safe_write import atomic_write

from ..types import Status
from .errors import MapFileError, MapIntegrityWarning
from .grid import AXIS_HUMAN, AXIS_UNITS, STATE_AXES, MapGrid, check_axis
from .shipped import SHIPPED_SHA256, maps_dir, regular_map_file

SCHEMA = 'rftgls.capacity_map'
SCHEMA_VERSION = 2
# Versions this reader handles: 1 (no /support_margin: the edge-margin rule is off) and 2.
READABLE_VERSIONS = (1, 2)
STATUS_NAMES = tuple(s.value for s in Status)          # code -> name written by this version
VOLATILE_ATTRS = ('build_time_utc',)
REQUIRED_ATTRS = ('schema', 'schema_version', 'robot', 'medium', 'method', 'rft_model',
                  'n_twists', 'scaling_force_N', 'scaling_length_m', 'package_version',
                  'build_command', 'provenance_json')
AXES = STATE_AXES + ('phi',)
HASH_ATTR = 'content_sha256'
# The root attributes that change what a query answers (the rest describe the build).
ANSWER_ATTRS = ('robot', 'medium', 'method', 'rft_model', 'n_twists', 'scaling_force_N',
                'scaling_length_m', 'provenance_json')
# Status names earlier versions wrote into /status's table. Allowed in the table as long as no
# node uses them ('extrapolated' was never stored at a node: maps hold node values only).
RETIRED_STATUS_NAMES = ('extrapolated',)


@dataclass(eq=False)
class NodeAnswers:
    """The answers a map stores at its nodes, shared by robot maps (MapData) and described
    maps (maps/described.py). Arrays are shaped like `grid.shape` (+ (3,) for the twists).

    status: uint8 codes into STATUS_NAMES. reason: uint8 codes into reason_names.
    attrs: the root attributes other than schema/schema_version (strings and numbers).
    """

    grid: Any
    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    reason_names: tuple[str, ...]
    attrs: dict = field(default_factory=dict)


@dataclass(eq=False)
class MapData(NodeAnswers):
    """Everything a robot map file holds, in memory: the node answers over a MapGrid (the four
    state axes and phi), plus how its content was verified and its support margins."""

    grid: MapGrid
    # How load_map established the content: 'shipped' (matches the hash recorded in the
    # package), 'verified' (matches its own content_sha256), 'unverified' (no hash stored),
    # '' (built in memory, not loaded).
    integrity: str = ''
    # Schema 2 (maps/edge.py): support margin per node and pull (P, Nh, Nb, N1, N2), scaled
    # metric, >= 0 where the weight is held, <= 0 where not, NaN without a surface. None for
    # a version-1 file (the edge-margin rule is then off).
    support_margin: np.ndarray | None = None
    # Its gradient along the state axes (P, Nh, Nb, N1, N2, 4): 1/m for h, 1/rad for angles.
    support_margin_grad: np.ndarray | None = None

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


def _canon_attr(value) -> bytes:
    """Type-tagged, exact text of an attribute (h5py gives back int, float or str)."""
    if isinstance(value, (bool, np.bool_)):
        return b'b:%d' % int(value)
    if isinstance(value, (int, np.integer)):
        return b'i:%d' % int(value)
    if isinstance(value, (float, np.floating)):
        return b'f:' + float(value).hex().encode()
    return b's:' + str(value).encode('utf-8')


def empty_answers(shape: tuple[int, ...], twist_dim: int):
    """Answer arrays to fill, (capacity_N, slip_twist_scaled, slip_twist, status, reasons):
    NaN capacities and twists (twist_dim components last), status 0, reasons None (object)."""
    return (np.full(shape, np.nan), np.full(shape + (twist_dim,), np.nan),
            np.full(shape + (twist_dim,), np.nan), np.zeros(shape, dtype=np.uint8),
            np.empty(shape, dtype=object))


class ContentHash:
    """SHA-256 over a map's answers, item by item (robot maps and described maps alike).

    Each item is fed as its name, its payload length and the payload; arrays are cast to the
    stored dtype and fed as dtype, shape and little-endian C-order bytes. The first bytes are
    the map kind's tag, so two kinds never share a digest.
    """

    def __init__(self, tag: bytes):
        self._h = hashlib.sha256(tag)

    def feed(self, name: str, payload: bytes) -> None:
        self._h.update(name.encode() + b'\0' + len(payload).to_bytes(8, 'little') + payload)

    def array(self, name: str, a, dtype: str) -> None:
        a = np.ascontiguousarray(np.asarray(a).astype(dtype, copy=False))
        self.feed(name, f'{a.dtype.str}{a.shape}'.encode() + b'\0' + a.tobytes())

    def answers(self, capacity_N, slip_twist_scaled, slip_twist, status, status_names, reason,
                reason_names) -> None:
        """The answer arrays and their name tables, in the stored dtypes and this order."""
        self.array('capacity_N', capacity_N, '<f4')
        self.array('slip_twist_scaled', slip_twist_scaled, '<f4')
        self.array('slip_twist', slip_twist, '<f4')
        self.array('status', status, 'u1')
        self.feed('status_names', '\n'.join(map(str, status_names)).encode())
        self.array('reason', reason, 'u1')
        self.feed('reason_names', '\n'.join(map(str, reason_names)).encode())

    def hexdigest(self) -> str:
        return self._h.hexdigest()


def content_sha256(grid: MapGrid, capacity_N, slip_twist_scaled, slip_twist, status,
                   status_names, reason, reason_names, attrs: dict,
                   support_margin=None, support_margin_grad=None) -> str:
    """Hex SHA-256 over everything that defines a map's answers, in the stored dtypes.

    Each item is fed as name, dtype, shape and little-endian C-order bytes (or tagged text for
    attributes and name tables), so a changed value, a relabelled pull, a flipped bit in an
    axis or a re-ordered status table all change the digest.
    """
    h = ContentHash(b'rftgls.capacity_map/content/1\0')
    for key in ANSWER_ATTRS:
        h.feed(f'@{key}', _canon_attr(attrs.get(key, '')))
    for name in AXES:
        h.array(f'axes/{name}', getattr(grid, name), '<f8')
    h.feed('axes/pull', '\n'.join(grid.pulls).encode())
    h.answers(capacity_N, slip_twist_scaled, slip_twist, status, status_names, reason,
              reason_names)
    if support_margin is not None:   # schema 2; a version-1 file keeps its digest
        h.array('support_margin', support_margin, '<f4')
        h.array('support_margin_grad', support_margin_grad, '<f4')
    return h.hexdigest()


def _shipped_hash(path: Path) -> str | None:
    """The hash recorded in the package if `path` is a shipped map in its installed place."""
    try:
        here = path.resolve()
        if here.parent != maps_dir().resolve():
            return None
    except OSError:
        return None
    return SHIPPED_SHA256.get(here.name)


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
    reason_names = list(data.reason_names) if data.reason_names else ['']
    margin, grad = data.support_margin, data.support_margin_grad
    if (margin is None) != (grad is None):
        raise ValueError('support_margin and support_margin_grad go together (schema 2)')
    if margin is not None and margin.shape != g.shape[:-1]:
        raise ValueError(f'support_margin has shape {margin.shape}, grid needs {g.shape[:-1]}')
    if grad is not None and grad.shape != g.shape[:-1] + (4,):
        raise ValueError(f'support_margin_grad has shape {grad.shape}, grid needs '
                         f'{g.shape[:-1] + (4,)}')
    digest = content_sha256(g, data.capacity_N, data.slip_twist_scaled, data.slip_twist,
                            data.status, STATUS_NAMES, data.reason, reason_names, data.attrs,
                            margin, grad)
    with atomic_write(path) as tmp, h5py.File(tmp, 'w', track_order=True) as f:
        f.attrs['schema'] = SCHEMA
        # A map without the support margin (built in memory by older code) stays version 1.
        f.attrs['schema_version'] = SCHEMA_VERSION if margin is not None else 1
        for key in REQUIRED_ATTRS[2:] + VOLATILE_ATTRS:
            if key in data.attrs:
                f.attrs[key] = data.attrs[key]
        f.attrs[HASH_ATTR] = digest
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
        rs.attrs['reason_names'] = reason_names
        if margin is not None:
            f.create_dataset('support_margin', data=margin.astype(np.float32), **comp)
            assert grad is not None
            f.create_dataset('support_margin_grad', data=grad.astype(np.float32), **comp)
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


# What one dataset may expand to in memory. A compressed (or never written, fill-valued)
# dataset can declare any shape in a small file; the shipped maps' largest is 0.1 MB.
MAX_DATASET_BYTES = 1 << 30


def check_dataset_size(ds: h5py.Dataset) -> None:
    """MapFileError when reading `ds` would take more than MAX_DATASET_BYTES of memory."""
    if float(np.prod(ds.shape, dtype=float)) * ds.dtype.itemsize > MAX_DATASET_BYTES:
        raise MapFileError(f'dataset {ds.name} of shape {ds.shape} would take more than '
                           f'{MAX_DATASET_BYTES >> 20} MiB to read')


def read_dataset(ds: h5py.Dataset) -> np.ndarray:
    """The values of `ds`, after check_dataset_size."""
    check_dataset_size(ds)
    return ds[()]


def _dataset(f: h5py.File, name: str, shape: tuple, kind: str) -> np.ndarray:
    if name not in f or not isinstance(f[name], h5py.Dataset):
        raise MapFileError(f'dataset /{name} is missing')
    ds = f[name]
    check_dataset_size(ds)
    if ds.shape != shape:
        raise MapFileError(f'dataset /{name} has shape {ds.shape}, the axes need {shape}')
    if ds.dtype.kind not in kind:
        raise MapFileError(f'dataset /{name} has dtype {ds.dtype}, expected kind {kind!r}')
    return ds[()]


def _read(f: h5py.File, expected_sha256: str | None = None) -> MapData:
    schema = _attr(f.attrs.get('schema'))
    if schema != SCHEMA:
        raise MapFileError(f'not a capacity map (schema attribute {schema!r}, '
                           f'expected {SCHEMA!r})')
    version = _attr(f.attrs.get('schema_version'))
    if not isinstance(version, int) or isinstance(version, bool):
        raise MapFileError(f'schema_version {version!r} is not an integer')
    if version not in READABLE_VERSIONS:
        newer = ' (newer than this reader)' if version > SCHEMA_VERSION else ''
        raise MapFileError(f'schema version {version}{newer}; this reader handles '
                           f'versions {", ".join(map(str, READABLE_VERSIONS))}')
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
        values = read_dataset(f[key])
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
    unknown = [n for n in names if n not in known and n not in RETIRED_STATUS_NAMES]
    if unknown:
        raise MapFileError(f'/status names unknown statuses: {", ".join(map(str, unknown))}')
    if status.size and int(status.max()) >= len(names):
        raise MapFileError(f'/status code {int(status.max())} is outside its table '
                           f'({len(names)} names)')
    used = set(np.unique(status).tolist()) if status.size else set()
    retired = sorted({names[c] for c in used if names[c] not in known})
    if retired:
        raise MapFileError(f'/status uses the retired status {", ".join(retired)}; rebuild '
                           'the map with this version')
    reason_names = _attr(f['reason'].attrs.get('reason_names'))
    if not isinstance(reason_names, list) or not reason_names:
        raise MapFileError('/reason has no reason_names table')
    if reason.size and int(reason.max()) >= len(reason_names):
        raise MapFileError(f'/reason code {int(reason.max())} is outside its table')

    margin = grad = None
    if version >= 2:
        margin = _dataset(f, 'support_margin', shape[:-1], 'f')
        grad = _dataset(f, 'support_margin_grad', shape[:-1] + (4,), 'f')
    elif 'support_margin' in f or 'support_margin_grad' in f:
        raise MapFileError('schema version 1 file carries /support_margin (version 2 data)')

    stored = _attr(f.attrs.get(HASH_ATTR)) if HASH_ATTR in f.attrs else None
    digest = None
    if stored is not None or expected_sha256 is not None:
        digest = content_sha256(grid, cap, ts, tr, status, names, reason, reason_names, attrs,
                                margin, grad)
    if expected_sha256 is not None and digest != expected_sha256:
        assert digest is not None
        raise MapFileError(f'content hash {digest[:12]}... does not match the hash recorded '
                           f'for this shipped map ({expected_sha256[:12]}...): the file was '
                           'changed or damaged; reinstall it')
    if stored is not None and digest != stored:
        assert digest is not None
        raise MapFileError(f'content hash {digest[:12]}... does not match its '
                           f'{HASH_ATTR} {str(stored)[:12]}...: the values were changed or '
                           'damaged after the map was written')
    integrity = ('shipped' if expected_sha256 is not None
                 else 'verified' if stored is not None else 'unverified')
    # Re-code to this version's table, so a file written with another order still reads
    # (retired names are unused, checked above).
    recode = np.array([STATUS_NAMES.index(n) if n in known else 255 for n in names],
                      dtype=np.uint8)
    status = recode[status]

    valued = np.isin(status, [STATUS_NAMES.index(s.value) for s in Status if s.has_value])
    if not np.all(np.isfinite(cap[valued])) or np.any(cap[valued] < 0):
        raise MapFileError('capacity_N is negative or not finite at a node with a value')
    norms = np.linalg.norm(ts[valued].astype(np.float64), axis=-1)
    if not np.all(np.abs(norms - 1.0) < 1e-3):
        raise MapFileError('slip_twist_scaled is not a unit vector at a node with a value')
    if margin is not None:
        # Signed by support: >= 0 where a pull angle has a value (the weight is held), <= 0
        # where none has; NaN (no surface) only at a node without any value.
        held = valued.any(axis=-1)
        if np.any(np.isinf(margin)) or np.any(held & ~(margin >= 0.0)) \
                or np.any(~held & (margin > 0.0)):
            raise MapFileError('support_margin does not match the node statuses (must be '
                               '>= 0 where the weight is held, <= 0 or NaN where it is not)')
        assert grad is not None
        if np.any(np.isinf(grad)):
            raise MapFileError('support_margin_grad is infinite')
    return MapData(grid=grid, capacity_N=cap, slip_twist_scaled=ts, slip_twist=tr,
                   status=status, reason=reason, reason_names=tuple(reason_names), attrs=attrs,
                   integrity=integrity, support_margin=margin, support_margin_grad=grad)


def load_map(path: str | Path, expected_sha256: str | None = None) -> MapData:
    """Read, validate and verify a map file. Any problem -> MapFileError('<path>: <one line>').

    expected_sha256: the content hash the caller requires; by default the hash recorded in the
    package when `path` is a shipped map in maps_dir(), else none (the file's own stored hash
    is always checked). A file without a stored hash loads with a MapIntegrityWarning and
    `integrity == 'unverified'` (nodes should log it loudly).
    """
    path = regular_map_file(path)
    if expected_sha256 is None:
        expected_sha256 = _shipped_hash(path)
    try:
        with h5py.File(path, 'r') as f:
            data = _read(f, expected_sha256)
    except MapFileError as exc:
        raise MapFileError(f'{path}: {exc}') from None
    except (OSError, KeyError, TypeError, ValueError, RuntimeError) as exc:
        # h5py reports truncated/corrupt files and unreadable chunks as OSError/KeyError.
        msg = ' '.join(str(exc).split()) or type(exc).__name__
        raise MapFileError(f'{path}: unreadable or corrupt HDF5 map ({msg})') from None
    if data.integrity == 'unverified':
        msg = (f'{path}: map has no {HASH_ATTR}: its values cannot be verified (rebuild it, '
               'or re-save it with save_map, which writes the hash)')
        warnings.warn(msg, MapIntegrityWarning, stacklevel=2)
    return data
