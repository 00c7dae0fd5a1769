"""Newton on the load ray for a warm step: one seed, a few seeds batched, the local Jacobian.

The same steps, tolerance, trust region and backtracking as `newton.newton_on_sphere`, written
for a handful of 3-vectors in the scaled wrench space (docs/design/warm-direct.md).
"""
from __future__ import annotations

import math

import numpy as np

from .base import GLSProblem
from .newton import unit_rows
from .scaling import DiagonalScaling
from .warm_kernels import HAVE_NUMBA, newton_batch_twists, newton_update, unit_rows_over


def scaled_evaluator(problem: GLSProblem):
    """Scaled unit twists (M, 3) -> scaled wrenches, as
    sc.wrench_to_scaled(problem.wrenches(sc.twist_from_scaled(ts))) computes them (bitwise:
    the same divisions, sums and square root), with the scaling's diagonal taken once and the
    twists' normalisation in one small kernel (numpy's took ~5 us of a few-twist call)."""
    sc = problem.scaling
    plain = (isinstance(sc, DiagonalScaling)
             and type(sc).twist_from_scaled is DiagonalScaling.twist_from_scaled
             and type(sc).wrench_to_scaled is DiagonalScaling.wrench_to_scaled)
    if not plain or not HAVE_NUMBA:
        return lambda ts: sc.wrench_to_scaled(problem.wrenches(sc.twist_from_scaled(ts)))
    diag = np.array(sc.diag, dtype=float)

    def eval_scaled(ts: np.ndarray) -> np.ndarray:
        return problem.wrenches(unit_rows_over(np.asarray(ts, dtype=float), diag)) / diag
    return eval_scaled


def fd_batch(t: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The twist, its two forward-difference neighbours (as newton._tangent_basis), u, v."""
    k = int(np.argmin(np.abs(t)))
    helper = np.zeros(3)
    helper[k] = 1.0
    u = np.array([t[1] * helper[2] - t[2] * helper[1], t[2] * helper[0] - t[0] * helper[2],
                  t[0] * helper[1] - t[1] * helper[0]])
    u /= math.sqrt(u @ u)
    v = np.array([t[1] * u[2] - t[2] * u[1], t[2] * u[0] - t[0] * u[2],
                  t[0] * u[1] - t[1] * u[0]])
    batch = np.stack([t, t + h * u, t + h * v])
    batch[1:] /= np.linalg.norm(batch[1:], axis=1, keepdims=True)
    return batch, u, v


def newton_one(eval_scaled, d: np.ndarray, seed: np.ndarray, rtol: float = 1e-12,
               fd_step: float = 1e-7, max_iter: int = 10, first: np.ndarray | None = None
               ) -> tuple[np.ndarray, float, float, np.ndarray, bool, tuple]:
    """`newton.newton_on_sphere` for one seed, with the same steps, tolerance, trust region
    and backtracking, written for a single 3-vector (the batched version's array overhead is
    most of a warm step). `first`: the wrenches of the seed's first batch (fd_batch), when the
    caller evaluated them already. Returns (twist, s, residual, jacobian (2, 2), converged,
    local) with local = (W(t), u, v, dW/du, dW/dv) at that twist (the local linear model)."""
    e1 = np.array([-d[1], d[0], 0.0])
    t = seed / np.linalg.norm(seed)
    best_t, best_r, best_s = t, math.inf, 0.0
    best_step = np.zeros(2)
    bu = bv = np.zeros(3)
    jac = np.zeros((2, 2))
    local: tuple = ()
    lam = 1.0
    for it in range(max_iter):
        batch, u, v = fd_batch(t, fd_step)
        w = first if (it == 0 and first is not None) else eval_scaled(batch)
        r = np.array([e1 @ w[0], w[0, 2]])
        rn = math.hypot(r[0], r[1])
        dw1, dw2 = w[1] - w[0], w[2] - w[0]
        j_now = np.array([[e1 @ dw1, e1 @ dw2], [dw1[2], dw2[2]]]) / fd_step
        improved = rn < best_r
        if improved:
            best_t, best_r, best_s, jac = t, rn, float(d @ w[0]), j_now
            local = (w[0], u, v, dw1 / fd_step, dw2 / fd_step)
        if best_r <= rtol * max(abs(best_s), 1e-3):
            return best_t, best_s, best_r, jac, True, local
        if improved:
            det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
            if det != 0.0:
                step = -np.array([jac[1, 1] * r[0] - jac[0, 1] * r[1],
                                  -jac[1, 0] * r[0] + jac[0, 0] * r[1]]) / det
            else:
                step = -np.linalg.pinv(jac) @ r
            nrm = math.hypot(step[0], step[1])
            step *= min(1.0, 0.3 / max(nrm, 1e-300))   # trust region, rad
            best_step, bu, bv, lam = step, u, v, 1.0
        else:
            lam *= 0.5
            if lam < 1e-6:
                break
        t = best_t + lam * (best_step[0] * bu + best_step[1] * bv)
        t = t / math.sqrt(t @ t)
    return best_t, best_s, best_r, jac, False, local


def newton_batch(eval_scaled, d: np.ndarray, seeds: np.ndarray, rtol: float = 1e-12,
                 fd_step: float = 1e-7, max_iter: int = 40):
    """`newton.newton_on_sphere` (same steps, tolerance, trust region, backtracking and
    returns) for a handful of seeds, each iteration's arithmetic in two scalar kernels
    (newton_batch_twists, newton_update): numpy's per-call overhead on five seeds cost
    more than the wrench calls themselves. The cold solve keeps the reference version; a
    test holds the two equal."""
    d = np.ascontiguousarray(d, dtype=float)
    t = np.ascontiguousarray(unit_rows(np.asarray(seeds, dtype=float)))
    k = len(t)
    best_t = t.copy()
    best_r = np.full(k, np.inf)
    best_step = np.zeros((k, 2))
    bu, bv = np.zeros((k, 3)), np.zeros((k, 3))
    lam = np.ones(k)
    jac = np.zeros((k, 2, 2))
    s = np.zeros(k)
    conv = np.zeros(k, dtype=np.bool_)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        batch, u, v = newton_batch_twists(t, fd_step)
        w = np.ascontiguousarray(eval_scaled(batch), dtype=float)
        if newton_update(t, u, v, w, d, fd_step, rtol, best_t, best_r, best_step, bu, bv,
                          lam, jac, s, conv):
            break
    return best_t, s, best_r, jac, conv, it


def tangent_jacobian(local: tuple, d: np.ndarray) -> np.ndarray:
    """The residual's derivative on the sphere's tangent plane as a (2, 3) map of twist
    increments: independent of the (u, v) basis, which Newton picks per twist and which
    swaps where the twist's smallest component changes."""
    _, u, v, du, dv = local
    proj = np.array([[-d[1], d[0], 0.0], [0.0, 0.0, 1.0]])
    return np.outer(proj @ du, u) + np.outer(proj @ dv, v)
