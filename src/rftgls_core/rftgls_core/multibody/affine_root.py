"""roots.closure_root for the equations the simulation solves, in one compiled loop.

Every balance of the simulation is three equations affine in the parts' total wrench W(xi)
and the base twist xi itself:

    R(x) = A W(xi) + B xi + c,      xi = x * ts                           (x scaled, ts > 0)

with (balance.py) A = diag(1 / (s_F, s_F, s_F L_c)), B = -M / dt scaled the same way (the
inertia where the robot falls) and c = the loads and M xi_prev / dt, scaled.

`affine_root` runs the very steps of roots.closure_root (Levenberg-Marquardt with
forward-difference Jacobians down the ramp schedule, evaluate.py's ramped RFT) inside numba,
where a Python loop spent ~0.2 ms of overhead per evaluation against ~20 us of RFT; without
numba it calls roots.closure_root on the same map. Each part's wrench at the root comes back
with it (Root.extra).
"""
from __future__ import annotations

import math

import numpy as np

from ..rft import kernels
from .contact import Contact
from .evaluate import LEADING_TOL, REST_TOL
from .roots import ACCEPT, EPS_SCHEDULE, Root, closure_root

MAX_ITER = 40

if kernels.AVAILABLE:
    import numba

    from .evaluate import _block

    @numba.njit(cache=True, nogil=True)
    def _residuals(xs, ts, a, b, c, fo, pid, cols, mu, eps, creep, scale, fxs, fzs, per,
                   res):   # pragma: no cover - jitted
        """R at the scaled twists xs (K, 3) into res (K, 3); each part's wrench (N) into per
        (K, P, 3). fo, pid, cols: evaluate._block's; fxs, fzs: its scratch."""
        k_n = xs.shape[0]
        tw = np.empty((3, k_n))
        for k in range(k_n):
            for i in range(3):
                tw[i, k] = xs[k, i] * ts[i]
        _block(tw, 0, k_n, fo, pid, cols, mu, eps, creep, REST_TOL, LEADING_TOL, fxs, fzs,
               per)
        for k in range(k_n):
            wsum = np.zeros(3)
            for j in range(per.shape[1]):
                for i in range(3):
                    per[k, j, i] *= scale[j]
                    wsum[i] += per[k, j, i]
            for i in range(3):
                v = c[i]
                for m in range(3):
                    v += a[i, m] * wsum[m] + b[i, m] * tw[m, k]
                res[k, i] = v

    @numba.njit(cache=True, nogil=True)
    def _norm3(v):   # pragma: no cover - jitted
        return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])

    @numba.njit(cache=True, nogil=True)
    def _probes(x, step, fd, first, last, out):   # pragma: no cover - jitted
        """Rows first..last-1 of the probe layout into out (last - first, 3): row 0 is
        x + step, row i the same plus fd on coordinate i - 1 (the forward differences).
        Each row is summed in that order whichever rows are asked for, so a point probed
        alone gets the very twist it gets probed with its differences."""
        for i in range(first, last):
            for m in range(3):
                out[i - first, m] = x[m] + step[m] + (fd if i == m + 1 else 0.0)

    @numba.njit(cache=True, nogil=True)
    def _lm(x0, ts, a, b, c, fo, pid, cols, mu, creep, scale, eps_sched, tol, bound,
            max_iter, per_out, res_out):   # pragma: no cover - jitted
        """roots.closure_root's stages; returns (x, |R| at the last eps, calls, beyond) and
        puts R and the parts' wrenches at x into res_out[0], per_out[0] (the last eps and
        creep) and res_out[1], per_out[1] (exact RFT: eps = creep = 0).

        A point's three forward-difference probes are evaluated only once the point is kept
        and is not yet a root: a trial step the damping rejects, or one that lands within
        the stage's tolerance, costs one RFT twist instead of four. Each twist owns its
        sums in evaluate._block, so R at a point is the same bits probed alone or in a
        batch, and the iterates are those of the four-probe loop."""
        n_parts = scale.shape[0]
        fxs = np.empty(cols.shape[1])            # evaluate._block's scratch
        fzs = np.empty(cols.shape[1])
        x = x0.copy()
        no_step = np.zeros(3)
        base = np.empty((1, 3))                  # the current point, R there in res
        res = np.empty((1, 3))
        diff = np.empty((3, 3))                  # its forward-difference probes
        res_d = np.empty((3, 3))
        trial_pt = np.empty((1, 3))
        res_t = np.empty((1, 3))
        per1 = np.empty((1, n_parts, 3))         # scratch: parts' wrenches, unused here
        per3 = np.empty((3, n_parts, 3))
        calls = 0
        nf = np.inf
        for s in range(eps_sched.shape[0]):
            e = eps_sched[s]
            stage_tol = tol if s == eps_sched.shape[0] - 1 else max(tol, 1e-2 * e)
            fd = min(1e-7, 1e-3 * e) * max(1.0, _norm3(x))
            _probes(x, no_step, fd, 0, 1, base)
            _residuals(base, ts, a, b, c, fo, pid, cols, mu, e, creep, scale, fxs, fzs, per1,
                       res)
            calls += 1
            nf = _norm3(res[0])
            lam = 1e-6
            for _ in range(max_iter):
                if nf <= stage_tol or _norm3(x) > bound:
                    break
                _probes(x, no_step, fd, 1, 4, diff)
                _residuals(diff, ts, a, b, c, fo, pid, cols, mu, e, creep, scale, fxs,
                           fzs, per3, res_d)
                calls += 1
                jac = np.empty((3, 3))
                for i in range(3):
                    for m in range(3):
                        jac[i, m] = (res_d[m, i] - res[0, i]) / fd
                jtj = jac.T @ jac
                jtf = jac.T @ res[0]
                improved = False
                for trial in range(13):
                    if trial == 0:
                        mat = jac.copy()
                        rhs = -res[0].copy()
                    else:
                        mat = jtj.copy()
                        for i in range(3):
                            mat[i, i] += lam * (jtj[i, i] + 1e-12)
                        rhs = -jtf
                    ok = abs(np.linalg.det(mat)) > 0.0
                    if ok:
                        step = np.linalg.solve(mat, rhs)
                        ok = np.all(np.isfinite(step))
                    if ok:
                        _probes(x, step, fd, 0, 1, trial_pt)
                        _residuals(trial_pt, ts, a, b, c, fo, pid, cols, mu, e, creep,
                                   scale, fxs, fzs, per1, res_t)
                        calls += 1
                        nt = _norm3(res_t[0])
                        if nt < nf:
                            for m in range(3):
                                x[m] += step[m]
                            res[:] = res_t
                            nf = nt
                            improved = True
                            if trial > 0:
                                lam = max(lam / 4.0, 1e-12)
                            break
                    if trial > 0:
                        lam *= 8.0
                if not improved:
                    break
            if _norm3(x) > bound:
                break
        pt = np.empty((1, 3))
        pt[0] = x
        _residuals(pt, ts, a, b, c, fo, pid, cols, mu, eps_sched[-1], creep, scale, fxs, fzs,
                   per_out[0:1], res_out[0:1])
        _residuals(pt, ts, a, b, c, fo, pid, cols, mu, 0.0, 0.0, scale, fxs, fzs,
                   per_out[1:2], res_out[1:2])
        return x, nf, calls, _norm3(x) > bound


def affine_root(contact: Contact, x0: np.ndarray, ts: np.ndarray, a: np.ndarray,
                b: np.ndarray, c: np.ndarray, tol: float, rates: bool = True,
                eps: tuple[float, ...] = EPS_SCHEDULE, accept: float = ACCEPT,
                bound: float = np.inf, mask: np.ndarray | None = None,
                creep: float = 0.0) -> Root:
    """Root of R(x) = a W(x * ts) + b (x * ts) + c on RFT's closure near x0 (module doc);
    rates=False holds every leg still; mask: the parts W sums (default all). Root.extra:
    each part's wrench there, flattened (zero outside mask)."""
    assert contact.packed is not None
    pk = contact.packed
    off = contact._offsets if rates else np.zeros_like(contact._offsets)
    keep = np.ones(pk.n_parts) if mask is None else np.asarray(mask, dtype=float)
    ts, a, b, c = (np.ascontiguousarray(v, dtype=float) for v in (ts, a, b, c))
    if pk.columns is None:
        def f(x: np.ndarray, e: float = 0.0) -> np.ndarray:
            xi = x * ts
            per = contact.part_wrenches(xi, e, rates, creep) * keep[None, :, None]
            resid = per.sum(axis=1) @ a.T + xi @ b.T + c
            return np.column_stack([resid, per.reshape(len(x), -1)])
        return closure_root(f, x0, tol, eps, accept, bound)
    k = pk.body.bound()['fused']
    scale = k['xi'] * pk.counts * keep
    args = (ts, a, b, c, pk.facet_offsets(off), pk.pid, pk.columns, float(k['mu']))
    per = np.empty((2, pk.n_parts, 3))
    res = np.empty((2, 3))
    x, nf, calls, beyond = _lm(np.asarray(x0, dtype=float), *args, float(creep), scale,
                               np.asarray(eps, dtype=float), tol, bound, MAX_ITER, per, res)
    r_eps = float(np.linalg.norm(res[0]))
    r_exact = float(np.linalg.norm(res[1]))
    return Root(x, r_eps, r_exact, float(np.linalg.norm(res[1] - res[0])), float(eps[-1]),
                bool(not beyond and r_eps <= accept), int(calls) + 2, per[0].reshape(-1))
