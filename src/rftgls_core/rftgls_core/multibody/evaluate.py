"""Planar RFT wrenches of several parts, each with its own twist, in one pass.

A posed robot's buried parts (the base, each leg) move with the base twist xi plus their own
joint twist (contact.py). The root searches evaluate all of them at a handful of base twists
many times per step, so they are packed once per pose: every buried facet of every part bound
to the stress model by one rft/engine.BuriedBody (the same per-facet constants the capacity
solvers use), with the index of its part. One call then returns each part's wrench about p,

    out[k, j] = count_j * sum_{facets of part j} lambda_f * alpha_f * depth_f * area_f
                (twist of facet f = xs[k] + offset_j; offset_j = qdot_j J_j)

with lambda the leading weight: exactly RFT's (n . v_hat >= -1e-12, a facet at rest carries
nothing, as rft/kernels.py: eps = 0), or ramped over eps on the trailing side,

    lambda = clip(1 + (n . v_hat) / eps, 0, 1),

so that every facet the engine counts as leading keeps its full weight (the side faces of a
leg, whose normals are out of the plane, always do) and a facet at its switch carries a
fraction of its leading stress, as RFT's closure allows there (docs/design/closure.md). With
creep > 0 a facet slower than `creep` (m/s) carries the fraction |v| / creep of its stress:
the closure at rest (any fraction), resolved by speed. Both are the continuous companions the
balance is solved on (balance.py). The exact path (eps = creep = 0) matches
BuriedBody.planar_wrench to round-off (tests/core).
"""
from __future__ import annotations

import math

import numpy as np

from ..rft import kernels
from ..rft.engine import LEADING_TOL, BuriedBody
from ..rft.kernel_pairs import _cap, _coefficients, _cubics, _jit

REST_TOL = kernels.REST_TOL
BLOCK = kernels.BLOCK


@_jit(inline=True)
def _stress(ux, uy, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu, one):
    """alpha / xi_n of one facet for the unit direction u: the fused kernels' arithmetic
    (kernel_pairs: the three cubics of x1 = -u.z and x3 = n_d . u, then the friction cap)."""
    f1, f2, f3 = _cubics(ndx * ux + ndy * uy + ndz * uz, uz, p)
    ax = f1 * ndx + f2 * ux
    ay = f1 * ndy + f2 * uy
    az = f1 * ndz + f2 * uz - f3
    if capped:
        return _cap(ax, ay, az, nx, ny, nz, mu, one)
    return ax, ay, az


def _numpy(bound: dict, pid: np.ndarray, n_parts: int, xs: np.ndarray, offsets: np.ndarray,
           eps: float, creep: float = 0.0) -> np.ndarray:
    """Reference path (no numba): (K, P, 3)."""
    r, n, w = bound['r'], bound['n'], bound['w']
    out = np.zeros((len(xs), n_parts, 3))
    for j in range(n_parts):
        m = pid == j
        if not np.any(m):
            continue
        t = xs + offsets[j]
        rj, nj, wj = r[m], n[m], w[m]
        wy = t[:, 2:3]
        vx = t[:, 0:1] + wy * rj[:, 2]
        vz = t[:, 1:2] - wy * rj[:, 0]
        speed = np.sqrt(vx * vx + vz * vz)
        if eps > 0.0:
            moving = speed > 0.0
        else:
            moving = speed > REST_TOL * np.maximum(speed.max(axis=1, keepdims=True), 1e-300)
        inv = np.where(moving, 1.0 / np.where(moving, speed, 1.0), 0.0)
        ux, uz = vx * inv, vz * inv
        lead = ux * nj[:, 0] + uz * nj[:, 2]
        if eps > 0.0:
            lam = np.clip(1.0 + lead / eps, 0.0, 1.0) * moving
        else:
            lam = ((lead >= -LEADING_TOL) & moving).astype(float)
        if creep > 0.0:
            lam = lam * np.minimum(1.0, speed / creep)
        # the prepared model holds every buried facet: stress of part j's rows only
        sx, _, sz = _part_stress(bound['stress'], m, ux, uz)
        fx, fz = lam * sx * wj, lam * sz * wj
        out[:, j, 0] = fx.sum(axis=1)
        out[:, j, 1] = fz.sum(axis=1)
        out[:, j, 2] = (fx * rj[:, 2] - fz * rj[:, 0]).sum(axis=1)
    return out


def _part_stress(stress, mask: np.ndarray, ux: np.ndarray, uz: np.ndarray):
    """The prepared stress of the facets in mask for (K, F_part) directions."""
    full_x = np.zeros((ux.shape[0], mask.shape[0]))
    full_z = np.zeros_like(full_x)
    full_x[:, mask], full_z[:, mask] = ux, uz
    sx, sy, sz = stress.stress(full_x, np.zeros_like(full_x), full_z)
    return sx[:, mask], sy[:, mask], sz[:, mask]


if kernels.AVAILABLE:
    import numba

    @numba.njit(cache=True, fastmath={'contract'}, nogil=True, error_model='numpy')
    def _block(tw, k0, k1, offsets, pid, r, n, nd, poly, w, mu, eps, creep, rest_tol,
               lead_tol, out):   # pragma: no cover - jitted
        """Twists k0..k1 of tw (3, K): facets outside, twists inside (the SIMD lanes, as
        rft/kernels.py lays its loops out); each twist owns its accumulators."""
        nb = k1 - k0
        n_parts = offsets.shape[0]
        capped = mu < np.inf
        acc = np.zeros((n_parts, 3, nb))
        smax = np.zeros((n_parts, nb))
        if eps <= 0.0:
            for f in range(r.shape[0]):
                j = pid[f]
                rx, rz = r[f, 0], r[f, 2]
                ox, oz, ow = offsets[j, 0], offsets[j, 1], offsets[j, 2]
                for i in range(nb):
                    twy = tw[2, k0 + i] + ow
                    vx = tw[0, k0 + i] + ox + twy * rz
                    vz = tw[1, k0 + i] + oz - twy * rx
                    smax[j, i] = max(smax[j, i], vx * vx + vz * vz)
            for j in range(n_parts):
                for i in range(nb):
                    smax[j, i] = rest_tol * max(np.sqrt(smax[j, i]), 1e-300)
        for f in range(r.shape[0]):
            j = pid[f]
            rx, rz = r[f, 0], r[f, 2]
            nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
            ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
            p = _coefficients(poly, f)
            wf = w[f]
            ox, oz, ow = offsets[j, 0], offsets[j, 1], offsets[j, 2]
            for i in range(nb):
                twy = tw[2, k0 + i] + ow
                vx = tw[0, k0 + i] + ox + twy * rz
                vz = tw[1, k0 + i] + oz - twy * rx
                s = np.sqrt(vx * vx + vz * vz)
                moving = s > 0.0 if eps > 0.0 else s > smax[j, i]
                inv = 1.0 / s if moving else 0.0
                ux = vx * inv
                uz = vz * inv
                lead = ux * nx + uz * nz
                if eps > 0.0:
                    lam = min(1.0, max(0.0, 1.0 + lead / eps))
                else:
                    lam = 1.0 if lead >= -lead_tol else 0.0
                lam = lam if moving else 0.0
                if creep > 0.0 and s < creep:
                    lam *= s / creep
                if lam == 0.0 and s < math.inf:
                    # a trailing or resting facet would add (+-0) x its finite stress: nothing,
                    # to the bit; the root searches' few twists skip its cubics (a twist that
                    # is not finite still gets its NaN)
                    continue
                ax, ay, az = _stress(ux, 0.0, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu,
                                     1.0)
                fx = lam * wf * ax
                fz = lam * wf * az
                acc[j, 0, i] += fx
                acc[j, 1, i] += fz
                acc[j, 2, i] += rz * fx - rx * fz
        for j in range(n_parts):
            for c in range(3):
                for i in range(nb):
                    out[k0 + i, j, c] = acc[j, c, i]

    @numba.njit(cache=True, nogil=True)
    def _kernel(tw, offsets, pid, r, n, nd, poly, w, mu, eps, creep, rest_tol, lead_tol,
                out):   # pragma: no cover - jitted
        for b in range((tw.shape[1] + BLOCK - 1) // BLOCK):
            _block(tw, b * BLOCK, min(tw.shape[1], (b + 1) * BLOCK), offsets, pid, r, n, nd,
                   poly, w, mu, eps, creep, rest_tol, lead_tol, out)


class PackedParts:
    """Every buried facet of a pose's parts, bound once (facets: one Facets per part, world
    frame; ref: p; counts: how many identical parts each stands for)."""

    def __init__(self, facets: list, counts: list[int], model, ref: np.ndarray,
                 backend: str = 'auto'):
        from ..geometry.mesh import Facets
        self.n_parts = len(facets)
        self.counts = np.asarray(counts, dtype=float)
        buried = [f.subset(f.centroids[:, 2] < 0.0) for f in facets]
        pid = np.concatenate([np.full(len(b), j, dtype=np.int64) for j, b in enumerate(buried)])
        self.pid = pid
        self.body = BuriedBody(Facets.concatenate(buried), model, ref=ref, backend=backend)
        self._bound = self.body.bound()

    def wrenches(self, xs: np.ndarray, offsets: np.ndarray, eps: float = 0.0,
                 creep: float = 0.0) -> np.ndarray:
        """(K, P, 3) wrench of each part (times its count) for base twists xs (K, 3) and
        per-part twist offsets (P, 3); eps > 0 ramps the leading weight, creep > 0 (m/s) the
        stress of facets slower than creep (module doc)."""
        xs = np.ascontiguousarray(np.atleast_2d(xs), dtype=float)
        offsets = np.ascontiguousarray(offsets, dtype=float)
        k = self._bound['fused']
        if k is None or k['dtype'] is not np.float64:
            out = _numpy(self._bound, self.pid, self.n_parts, xs, offsets, eps, creep)
            return out * self.counts[None, :, None]
        out = np.zeros((len(xs), self.n_parts, 3))
        if len(self.pid):
            _kernel(np.ascontiguousarray(xs.T), offsets, self.pid, k['r'], k['n'], k['nd'],
                    k['poly'], k['w'], float(k['mu']), float(eps), float(creep), REST_TOL,
                    LEADING_TOL, out)
        return out * (k['xi'] * self.counts)[None, :, None]
