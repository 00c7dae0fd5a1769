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

import numpy as np

from ..geometry.mesh import Facets
from ..rft import kernels
from ..rft.engine import LEADING_TOL, BuriedBody
from ..rft.kernel_pairs import _cap, _cubics, _jit

REST_TOL = kernels.REST_TOL


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


# Rows of PackedParts.columns: one column per buried facet, so the compiled pass over the
# facets reads each quantity contiguously (and LLVM runs it in SIMD lanes).
RX, RZ, NX, NY, NZ, NDX, NDY, NDZ, W, POLY = range(10)    # POLY: the 30 cubic coefficients


def facet_columns(fused: dict) -> np.ndarray:
    """(POLY + 30, F): rows RX .. POLY + 29 from the fused kernel's per-facet arrays
    (rft/engine.py)."""
    r = fused['r']
    cols = np.empty((POLY + 30, len(r)))
    cols[RX], cols[RZ] = r[:, 0], r[:, 2]
    cols[NX:NZ + 1] = fused['n'].T
    cols[NDX:NDZ + 1] = fused['nd'].T
    cols[W] = fused['w']
    cols[POLY:] = fused['poly'].T
    return cols


if kernels.AVAILABLE:
    import numba

    @_jit(inline=True)
    def _row_coefficients(cols, f):   # pragma: no cover - jitted
        """Facet f's 30 cubic coefficients (kernel_pairs._coefficients' order) from columns."""
        return (cols[POLY, f], cols[POLY + 1, f], cols[POLY + 2, f], cols[POLY + 3, f],
                cols[POLY + 4, f], cols[POLY + 5, f], cols[POLY + 6, f], cols[POLY + 7, f],
                cols[POLY + 8, f], cols[POLY + 9, f], cols[POLY + 10, f], cols[POLY + 11, f],
                cols[POLY + 12, f], cols[POLY + 13, f], cols[POLY + 14, f],
                cols[POLY + 15, f], cols[POLY + 16, f], cols[POLY + 17, f],
                cols[POLY + 18, f], cols[POLY + 19, f], cols[POLY + 20, f],
                cols[POLY + 21, f], cols[POLY + 22, f], cols[POLY + 23, f],
                cols[POLY + 24, f], cols[POLY + 25, f], cols[POLY + 26, f],
                cols[POLY + 27, f], cols[POLY + 28, f], cols[POLY + 29, f])

    @_jit(inline=True)
    def _velocity(f, t0, t1, t2, fo, cols):   # pragma: no cover - jitted
        """Facet f's in-plane velocity (vx, vz) and its squared speed for the base twist
        (t0, t1, t2) plus its part's offset."""
        twy = t2 + fo[2, f]
        vx = t0 + fo[0, f] + twy * cols[RZ, f]
        vz = t1 + fo[1, f] - twy * cols[RX, f]
        return vx, vz, vx * vx + vz * vz

    @numba.njit(cache=True, fastmath={'contract'}, nogil=True, error_model='numpy')
    def _ramped_forces(t0, t1, t2, fo, cols, mu, eps, creep, capped, fxs,
                       fzs):   # pragma: no cover - jitted
        """Each facet's (Fx, Fz) for the twist (t0, t1, t2) on the ramped closure (module
        doc) into fxs, fzs: one pass whose SIMD lanes are the facets. (A loop that also
        held the exact rule, chosen per facet by eps, stayed scalar: 2x slower.)"""
        for f in range(cols.shape[1]):
            vx, vz, s2 = _velocity(f, t0, t1, t2, fo, cols)
            s = np.sqrt(s2)
            nx, ny, nz = cols[NX, f], cols[NY, f], cols[NZ, f]
            moving = s > 0.0
            inv = 1.0 / s if moving else 0.0
            ux = vx * inv
            uz = vz * inv
            lead = ux * nx + uz * nz
            lam = min(1.0, max(0.0, 1.0 + lead / eps))
            lam = lam if moving else 0.0
            if creep > 0.0 and s < creep:
                lam *= s / creep
            ax, ay, az = _stress(ux, 0.0, uz, nx, ny, nz, cols[NDX, f], cols[NDY, f],
                                 cols[NDZ, f], _row_coefficients(cols, f), capped, mu, 1.0)
            fxs[f] = lam * cols[W, f] * ax
            fzs[f] = lam * cols[W, f] * az

    @numba.njit(cache=True, fastmath={'contract'}, nogil=True, error_model='numpy')
    def _exact_forces(t0, t1, t2, fo, pid, cols, mu, lim, lead_tol, capped, fxs,
                      fzs):   # pragma: no cover - jitted
        """Each facet's (Fx, Fz) for the twist (t0, t1, t2) by RFT's own rule into fxs,
        fzs: leading with n . v_hat >= -lead_tol, at rest below lim[its part] (m/s)."""
        for f in range(cols.shape[1]):
            vx, vz, s2 = _velocity(f, t0, t1, t2, fo, cols)
            s = np.sqrt(s2)
            nx, ny, nz = cols[NX, f], cols[NY, f], cols[NZ, f]
            moving = s > lim[pid[f]]
            inv = 1.0 / s if moving else 0.0
            ux = vx * inv
            uz = vz * inv
            lead = ux * nx + uz * nz
            lam = 1.0 if lead >= -lead_tol else 0.0
            lam = lam if moving else 0.0
            ax, ay, az = _stress(ux, 0.0, uz, nx, ny, nz, cols[NDX, f], cols[NDY, f],
                                 cols[NDZ, f], _row_coefficients(cols, f), capped, mu, 1.0)
            fxs[f] = lam * cols[W, f] * ax
            fzs[f] = lam * cols[W, f] * az

    @numba.njit(cache=True, fastmath={'contract'}, nogil=True, error_model='numpy')
    def _block(tw, k0, k1, fo, pid, cols, mu, eps, creep, rest_tol, lead_tol, fxs, fzs,
               out):   # pragma: no cover - jitted
        """Twists k0..k1 of tw (3, K) into out[k0:k1] (K, P, 3). fo (3, F): each facet's
        part's twist offset; fxs, fzs (F,): scratch. The root searches ask for one to three
        twists at a time, so each twist is one pass over the facets (the SIMD lanes: facets)
        that puts each facet's force in fxs, fzs, then one sum over the facets in their order
        into their parts; the products and the order of every sum are those of a facet-by-
        facet loop, so the result does not depend on the lanes."""
        n_f = cols.shape[1]
        n_parts = out.shape[1]
        capped = mu < np.inf
        lim = np.zeros(n_parts)
        for k in range(k0, k1):
            t0, t1, t2 = tw[0, k], tw[1, k], tw[2, k]
            if eps <= 0.0:
                # the exact path: a facet is at rest below rest_tol x its part's top speed
                lim[:] = 0.0
                for f in range(n_f):
                    lim[pid[f]] = max(lim[pid[f]], _velocity(f, t0, t1, t2, fo, cols)[2])
                for j in range(n_parts):
                    lim[j] = rest_tol * max(np.sqrt(lim[j]), 1e-300)
            if eps > 0.0:
                _ramped_forces(t0, t1, t2, fo, cols, mu, eps, creep, capped, fxs, fzs)
            else:
                _exact_forces(t0, t1, t2, fo, pid, cols, mu, lim, lead_tol, capped, fxs, fzs)
            for j in range(n_parts):
                out[k, j, 0] = 0.0
                out[k, j, 1] = 0.0
                out[k, j, 2] = 0.0
            for f in range(n_f):
                j = pid[f]
                out[k, j, 0] += fxs[f]
                out[k, j, 1] += fzs[f]
                out[k, j, 2] += cols[RZ, f] * fxs[f] - cols[RX, f] * fzs[f]

    @numba.njit(cache=True, nogil=True)
    def _kernel(tw, fo, pid, cols, mu, eps, creep, rest_tol, lead_tol,
                out):   # pragma: no cover - jitted
        n_f = cols.shape[1]
        _block(tw, 0, tw.shape[1], fo, pid, cols, mu, eps, creep, rest_tol, lead_tol,
               np.empty(n_f), np.empty(n_f), out)


class PackedParts:
    """Every buried facet of a pose's parts, bound once (facets: one Facets per part, world
    frame; ref: p; counts: how many identical parts each stands for)."""

    def __init__(self, facets: list, counts: list[int], model, ref: np.ndarray,
                 backend: str = 'auto'):
        self.n_parts = len(facets)
        self.counts = np.asarray(counts, dtype=float)
        every = Facets.concatenate(facets)
        buried = every.centroids[:, 2] < 0.0
        self.pid = np.repeat(np.arange(len(facets), dtype=np.int64),
                             [len(f) for f in facets])[buried]
        self.body = BuriedBody(every.subset(buried), model, ref=ref, backend=backend)
        self._bound = self.body.bound()
        k = self._bound['fused']
        # the compiled path's facet columns (None: the numpy reference evaluates)
        self.columns = (facet_columns(k) if kernels.AVAILABLE and k is not None
                        and k['dtype'] is np.float64 else None)

    def facet_offsets(self, offsets: np.ndarray) -> np.ndarray:
        """(3, F) each buried facet's part twist offset from per-part offsets (P, 3)."""
        return np.ascontiguousarray(np.asarray(offsets, dtype=float)[self.pid].T)

    def wrenches(self, xs: np.ndarray, offsets: np.ndarray, eps: float = 0.0,
                 creep: float = 0.0) -> np.ndarray:
        """(K, P, 3) wrench of each part (times its count) for base twists xs (K, 3) and
        per-part twist offsets (P, 3); eps > 0 ramps the leading weight, creep > 0 (m/s) the
        stress of facets slower than creep (module doc)."""
        xs = np.ascontiguousarray(np.atleast_2d(xs), dtype=float)
        offsets = np.ascontiguousarray(offsets, dtype=float)
        if self.columns is None:
            out = _numpy(self._bound, self.pid, self.n_parts, xs, offsets, eps, creep)
            return out * self.counts[None, :, None]
        k = self._bound['fused']
        out = np.zeros((len(xs), self.n_parts, 3))
        if len(self.pid):
            _kernel(np.ascontiguousarray(xs.T), self.facet_offsets(offsets), self.pid,
                    self.columns, float(k['mu']), float(eps), float(creep), REST_TOL,
                    LEADING_TOL, out)
        return out * (k['xi'] * self.counts)[None, :, None]
