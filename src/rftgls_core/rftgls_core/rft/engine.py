"""Batched RFT: one posed body, M twists -> M wrenches in one vectorised call.

    F = sum_i alpha_i(n_i, v_i) |z_i| A_i  over buried (z_i < 0), leading (n_i . v_i >= 0) facets
    M = sum_i (c_i - ref) x F_i

World frame W: z up, free surface z = 0. Twists are given at a reference point `ref` (m):
spatial (vx, vy, vz, wx, wy, wz) in m/s and rad/s, or planar (vx, vz, wy) for sagittal
motion. Wrenches about `ref`: spatial (Fx, Fy, Fz, Mx, My, Mz) in N and N m, planar
(Fx, Fz, My).

"Model no more than the anchor needs": facets above the surface are dropped once, when the
body is bound (they carry no force whatever the twist); for planar twists a body symmetric
about a sagittal plane y = y0 is evaluated on one half with doubled weights, because mirror
facets give equal (Fx, Fz, My) and opposite (Fy, Mx, Mz).
"""
from __future__ import annotations

import numpy as np

from ..geometry.mesh import Facets
from . import kernels
from .base import StressModel

# A facet leads when n . v_hat >= -LEADING_TOL (Agarwal-style codes use >= 0).
LEADING_TOL = 1e-12
# Pairs per chunk: keeps the (chunk x F) temporaries inside the CPU caches.
_CHUNK_PAIRS = 16384
_PRECISIONS = {'float64': np.float64, 'float32': np.float32}


class BuriedBody:
    """The buried facets of a posed body, bound to a stress model and a reference point.

    facets: world-frame facets of the posed body (m). ref: reference point of twists and
    moments (m, world). mirror_y: y of the body's sagittal symmetry plane, or None.
    surface_z: height of the free surface (m). backend: 'auto' uses the fused numba kernel
    when the model offers one (Agarwal) and numba is installed, else 'numpy'.
    precision: 'float64' (default) or 'float32', the fused kernel's working precision per
    facet-twist pair (sums stay float64); float32 needs the fused kernel, costs ~1e-7
    relative (6e-8 on the bench's 6D sphere workload) and gains only ~15 %, so float64 is
    the default and nothing in the stack asks for float32.
    """

    def __init__(self, facets: Facets, model: StressModel, ref=(0.0, 0.0, 0.0),
                 mirror_y: float | None = None, surface_z: float = 0.0, backend: str = 'auto',
                 precision: str = 'float64'):
        if backend not in ('auto', 'numpy', 'numba'):
            raise ValueError(f"backend must be 'auto', 'numpy' or 'numba', got {backend!r}")
        if backend == 'numba' and not kernels.AVAILABLE:
            raise ValueError('backend numba requested but numba is not installed')
        if precision not in _PRECISIONS:
            raise ValueError(f"precision must be 'float64' or 'float32', got {precision!r}")
        self.model = model
        self.backend = backend
        self.precision = precision
        self.ref = np.asarray(ref, dtype=float).reshape(3)
        self.facets_total = len(facets)
        self._surface_z = surface_z
        buried = facets.centroids[:, 2] < surface_z
        self._under = facets.subset(buried)
        self._n_buried = int(buried.sum())
        self._full_bound: dict | None = None
        self._half = None
        if mirror_y is not None:
            under = self._under
            y = under.centroids[:, 1] - mirror_y
            tol = 1e-9 * max(1.0, float(np.abs(facets.centroids).max(initial=0.0)))
            keep = y > -tol
            weight = np.where(y > tol, 2.0, 1.0)[keep]
            # Planar twists (the sagittal solvers, every warm step) only ever need this half,
            # so it is prepared on its own and the full body waits until a spatial or
            # non-symmetric call asks for it (prepare is per facet: the same constants).
            self._half = self._bind(under.subset(keep), surface_z, weight)
        if precision != 'float64' and self.facets_active and not self.fused:
            raise ValueError(f'precision {precision} needs the fused numba kernel '
                             f'(backend {backend!r}, model {getattr(model, "name", model)!r})')

    @property
    def _full(self) -> dict:
        """The whole buried body bound (on first use)."""
        if self._full_bound is None:
            self._full_bound = self._bind(self._under, self._surface_z,
                                          np.ones(self._n_buried))
        return self._full_bound

    @property
    def facets_active(self) -> int:
        """Buried facets (the ones that can carry force)."""
        return self._n_buried

    def _bind(self, f: Facets, surface_z: float, multiplicity: np.ndarray) -> dict:
        r = f.centroids - self.ref
        w = f.areas * (surface_z - f.centroids[:, 2]) * multiplicity  # area x depth, m^3
        stress = self.model.prepare(f.normals)
        fused = None
        if self.backend != 'numpy' and kernels.AVAILABLE and hasattr(stress, 'fused_arrays'):
            fused = _kernel_arrays(stress.fused_arrays(), r, w, _PRECISIONS[self.precision])
        return {'r': np.ascontiguousarray(r), 'n': f.normals, 'w': np.ascontiguousarray(w),
                'wr': w[:, None] * r, 'stress': stress, 'len': len(w), 'fused': fused}

    def bound(self) -> dict:
        """The whole buried body as bound for evaluation (read it, never change it): r (F, 3)
        facet centroids from ref, n normals, w area x depth (m^3), stress (the prepared
        model) and fused (the fused kernel's arrays, or None): for evaluators of another
        leading weight (multibody/evaluate.py)."""
        return self._full

    @property
    def fused(self) -> bool:
        """True when evaluation runs in the fused numba kernel."""
        b = self._half if self._half is not None else self._full
        return b['fused'] is not None

    def wrench(self, twists: np.ndarray) -> np.ndarray:
        """Spatial wrenches (M, 6) about ref for spatial twists (M, 6) or (6,)."""
        t = _check_twists(twists, 6)
        out = np.zeros((len(t), 6))
        b = self._full
        if b['fused'] is not None:
            _run_fused(kernels.spatial_parallel, kernels.spatial_serial, b['fused'], t, out)
            return out[0] if np.ndim(twists) == 1 else out
        for s in _chunks(len(t), b['len']):
            v, w_ = t[s, :3], t[s, 3:]
            r = b['r']
            vx = v[:, 0:1] + w_[:, 1:2] * r[:, 2] - w_[:, 2:3] * r[:, 1]
            vy = v[:, 1:2] + w_[:, 2:3] * r[:, 0] - w_[:, 0:1] * r[:, 2]
            vz = v[:, 2:3] + w_[:, 0:1] * r[:, 1] - w_[:, 1:2] * r[:, 0]
            sx, sy, sz = self._masked_stress(b, vx, vy, vz)
            wr = b['wr']
            out[s, 0], out[s, 1], out[s, 2] = sx @ b['w'], sy @ b['w'], sz @ b['w']
            out[s, 3] = sz @ wr[:, 1] - sy @ wr[:, 2]
            out[s, 4] = sx @ wr[:, 2] - sz @ wr[:, 0]
            out[s, 5] = sy @ wr[:, 0] - sx @ wr[:, 1]
        return out[0] if np.ndim(twists) == 1 else out

    def planar_wrench(self, twists: np.ndarray, use_symmetry: bool = True) -> np.ndarray:
        """Planar wrenches (M, 3) = (Fx, Fz, My) about ref for twists (M, 3) = (vx, vz, wy)."""
        t = _check_twists(twists, 3)
        b = self._half if (use_symmetry and self._half is not None) else self._full
        out = np.zeros((len(t), 3))
        if b['fused'] is not None:
            _run_fused(kernels.planar_parallel, kernels.planar_serial, b['fused'], t, out)
            return out[0] if np.ndim(twists) == 1 else out
        r = b['r']
        for s in _chunks(len(t), b['len']):
            wy = t[s, 2:3]
            vx = t[s, 0:1] + wy * r[:, 2]
            vz = t[s, 1:2] - wy * r[:, 0]
            sx, _, sz = self._masked_stress(b, vx, np.zeros_like(vx), vz)
            out[s, 0] = sx @ b['w']
            out[s, 1] = sz @ b['w']
            out[s, 2] = sx @ b['wr'][:, 2] - sz @ b['wr'][:, 0]
        return out[0] if np.ndim(twists) == 1 else out

    @staticmethod
    def _masked_stress(b: dict, vx, vy, vz):
        speed = np.sqrt(vx * vx + vy * vy + vz * vz)
        # A facet on the instantaneous rotation axis has no direction and no RFT force.
        scale = speed.max(axis=1, keepdims=True) if speed.size else speed
        moving = speed > 1e-12 * np.maximum(scale, 1e-300)
        inv = np.where(moving, 1.0 / np.where(moving, speed, 1.0), 0.0)
        vx, vy, vz = vx * inv, vy * inv, vz * inv
        n = b['n']
        lead = (vx * n[:, 0] + vy * n[:, 1] + vz * n[:, 2] >= -LEADING_TOL) & moving
        sx, sy, sz = b['stress'].stress(vx, vy, vz)
        return (np.where(lead, sx, 0.0), np.where(lead, sy, 0.0), np.where(lead, sz, 0.0))


def _kernel_arrays(fused: dict, r: np.ndarray, w: np.ndarray, dtype) -> dict:
    """Per-facet constants as C-contiguous arrays of the kernels' working dtype."""
    def as_(a):
        return np.ascontiguousarray(a, dtype=dtype)
    return {'r': as_(r), 'n': as_(fused['n']), 'nd': as_(fused['nd']),
            'poly': as_(fused['poly']), 'w': as_(w), 'xi': float(fused['xi']),
            'mu': dtype(fused['mu']), 'c': kernels.constants(dtype), 'dtype': dtype}


def _run_fused(parallel, serial, k: dict, t: np.ndarray, out: np.ndarray) -> None:
    """Wrenches of twists t (M, width) into out (M, width), float64, via the fused kernels."""
    if k['w'].shape[0] == 0:
        return
    if k['dtype'] is not np.float64:
        # RFT is rate independent: unit-size twists keep float32 squares clear of overflow.
        t = t / np.abs(t).max(axis=1, keepdims=True)
    tw = np.ascontiguousarray(t.T, dtype=k['dtype'])  # (width, M): the SIMD lanes run over M
    args = (tw, k['r'], k['n'], k['nd'], k['poly'], k['w'], k['mu'], k['c'], out)
    if kernels.use_parallel(t.shape[0] * k['w'].shape[0]):
        kernels.run_parallel(parallel, *args)
    else:
        serial(*args)
    out *= k['xi']


def _check_twists(twists, width: int) -> np.ndarray:
    t = np.atleast_2d(np.asarray(twists, dtype=float))
    if t.ndim != 2 or t.shape[1] != width:
        raise ValueError(f'twists must have shape (M, {width}), got {np.shape(twists)}')
    fault = kernels.twist_fault(t) if kernels.AVAILABLE else (
        1 if not np.all(np.isfinite(t)) else 2 if np.any(np.abs(t).max(axis=1) == 0.0) else 0)
    if fault == 1:
        raise ValueError('twist contains NaN or inf')
    if fault == 2:
        raise ValueError('zero twist: RFT needs a direction of motion')
    return t


def _chunks(m: int, f: int):
    step = max(1, _CHUNK_PAIRS // max(f, 1))
    for start in range(0, m, step):
        yield slice(start, min(m, start + step))
