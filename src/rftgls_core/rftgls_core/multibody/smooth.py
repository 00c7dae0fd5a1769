"""RFT with a smoothed leading weight: the continuous companion the root search starts on.

RFT switches a facet on when it leads (n . v_hat >= 0) and off when it trails, so the wrench
of a body jumps across a plane in twist space per facet. Newton's finite differences across
such a jump see a derivative of size jump / step and wander. Here each facet's force is
weighted by

    lambda(n . v_hat) = clip(1 + (n . v_hat) / eps, 0, 1)

instead: the same RFT stress (kernels._stress, Agarwal 3D-RFT) with a ramp of width eps in
n . v_hat on the trailing side, so that every facet the engine counts as leading (n . v_hat >=
0: the side faces of a leg, whose normals are out of the plane, always) keeps its full
weight. Every value of the ramp is a member of RFT's closure at the switch (a facet at its
switch carries any fraction of its leading stress, docs/design/closure.md), and as eps -> 0 the
smoothed wrench returns to RFT's; roots.closure_root follows its root down a few eps and then
certifies it on the exact, set-valued map (walk-burrow-physics.md, "Well-posedness").

Same per-facet constants as the engine (BuriedBody.bound), planar twists only. The fused
numba loop when the engine bound one, numpy otherwise.
"""
from __future__ import annotations

import numpy as np

from ..rft import kernels
from ..rft.engine import BuriedBody

_stress = kernels._stress


def _smooth_numpy(b: dict, twists: np.ndarray, eps: float) -> np.ndarray:
    r, n, w = b['r'], b['n'], b['w']
    wy = twists[:, 2:3]
    vx = twists[:, 0:1] + wy * r[:, 2]
    vz = twists[:, 1:2] - wy * r[:, 0]
    speed = np.sqrt(vx * vx + vz * vz)
    moving = speed > 0.0
    inv = np.where(moving, 1.0 / np.where(moving, speed, 1.0), 0.0)
    ux, uz = vx * inv, vz * inv
    lam = np.clip(1.0 + (ux * n[:, 0] + uz * n[:, 2]) / eps, 0.0, 1.0) * moving
    sx, _, sz = b['stress'].stress(ux, np.zeros_like(ux), uz)
    fx, fz = lam * sx * w, lam * sz * w
    return np.column_stack([fx.sum(axis=1), fz.sum(axis=1),
                            (fx * r[:, 2] - fz * r[:, 0]).sum(axis=1)])


if kernels.AVAILABLE:
    import numba

    @numba.njit(cache=True, fastmath={'contract'}, nogil=True, error_model='numpy')
    def _smooth_kernel(tw, r, n, nd, poly, w, mu, eps, out):   # pragma: no cover - jitted
        nt = tw.shape[0]
        capped = mu < np.inf
        for f in range(r.shape[0]):
            rx, rz = r[f, 0], r[f, 2]
            nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
            ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
            p = poly[f]
            wf = w[f]
            for i in range(nt):
                vx = tw[i, 0] + tw[i, 2] * rz
                vz = tw[i, 1] - tw[i, 2] * rx
                s = np.sqrt(vx * vx + vz * vz)
                if s == 0.0:
                    continue
                ux = vx / s
                uz = vz / s
                lam = 1.0 + (ux * nx + uz * nz) / eps
                if lam <= 0.0:
                    continue
                if lam > 1.0:
                    lam = 1.0
                ax, ay, az = _stress(ux, 0.0, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu,
                                     1.0)
                fx = lam * wf * ax
                fz = lam * wf * az
                out[i, 0] += fx
                out[i, 1] += fz
                out[i, 2] += rz * fx - rx * fz


def smooth_planar(body: BuriedBody, twists: np.ndarray, eps: float) -> np.ndarray:
    """Planar wrenches (K, 3) of the body for twists (K, 3) with the leading weight ramped
    over eps (module doc); eps > 0."""
    b = body.bound()
    t = np.ascontiguousarray(np.atleast_2d(twists), dtype=float)
    k = b['fused']
    if k is None or k['dtype'] is not np.float64:
        return _smooth_numpy(b, t, eps)
    out = np.zeros((len(t), 3))
    if len(k['w']):
        _smooth_kernel(t, k['r'], k['n'], k['nd'], k['poly'], k['w'], float(k['mu']),
                       float(eps), out)
    return out * k['xi']
