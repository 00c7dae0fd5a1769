"""Newton's method on the unit twist sphere: find twists whose wrench lies on a load ray.

With d the unit load direction (scaled space), e1 = (-d_z, d_x, 0) and e2 = (0, 0, 1) span
the plane normal to d inside the wrench space; a twist t is on the ray when the residuals
r(t) = (e1 . Ws(t), e2 . Ws(t)) vanish, and its distance is s = d . Ws(t) > 0.
All seeds advance together: one batched wrench evaluation (3 twists per seed: the point and
two forward differences) per iteration; steps that do not reduce the residual are halved.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays: np.cross's arithmetic (bitwise the same
    numbers) without its axis handling, which costs more than the work on the few-row arrays
    of the solvers' hot loops (a third of a map build went to np.cross)."""
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def row_norms(x: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean norms of the last axis of a float array: np.linalg.norm(x, axis=-1)'s own
    arithmetic (a square root of the reduced squares, bitwise the same numbers) without its
    argument handling, which costs more than the work on the solvers' few-row arrays."""
    x = np.asarray(x, dtype=float)
    squares = np.add.reduce(x * x, axis=-1, keepdims=True)
    return np.sqrt(squares if keepdims else squares[..., 0])


def _tangent_basis(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal (U, V) (K, 3) spanning the tangent planes of unit vectors t (K, 3)."""
    helper = np.zeros_like(t)
    helper[np.arange(len(t)), np.argmin(np.abs(t), axis=1)] = 1.0
    u = cross_rows(t, helper)
    u /= row_norms(u, keepdims=True)
    return u, cross_rows(t, u)


def unit_rows(x: np.ndarray) -> np.ndarray:
    """Rows of x (..., n) scaled to unit length; an all-zero row stays zero."""
    n = row_norms(x, keepdims=True)
    return x / np.where(n > 0.0, n, 1.0)


def damped_newton_step(jac: np.ndarray, r: np.ndarray, max_norm: float = 0.3) -> np.ndarray:
    """Newton steps -J^-1 r per row (jac (k, n, n), r (k, n)), pseudo-inverse when a J is
    singular, each shortened to at most max_norm (rad on the unit sphere: a trust region)."""
    try:
        step = -np.linalg.solve(jac, r[..., None])[..., 0]
    except np.linalg.LinAlgError:
        step = -np.einsum('kij,kj->ki', np.linalg.pinv(jac), r)
    nrm = row_norms(step, keepdims=True)
    return step * np.minimum(1.0, max_norm / np.maximum(nrm, 1e-300))


def newton_on_sphere(eval_scaled: Callable[[np.ndarray], np.ndarray], d: np.ndarray,
                     seeds: np.ndarray, rtol: float = 1e-12, fd_step: float = 1e-7,
                     max_iter: int = 40):
    """Roots from seeds (K, 3) unit scaled twists. eval_scaled: (M, 3) twists -> (M, 3) Ws.

    Returns (t, s, residual, jacobian, converged, iterations) per seed: the best twist found,
    its distance along d, the norm of its off-ray residual, the 2x2 Jacobian there, whether
    the residual fell below rtol * s, and the iterations used.
    """
    e1 = np.array([-d[1], d[0], 0.0])
    e2 = np.array([0.0, 0.0, 1.0])
    proj = np.stack([e1, e2])                          # (2, 3)
    k = len(seeds)
    t = unit_rows(np.asarray(seeds, dtype=float))
    h = fd_step
    best_t = t.copy()
    best_r = np.full(k, np.inf)
    best_step = np.zeros((k, 2))
    best_uv = (np.zeros((k, 3)), np.zeros((k, 3)))
    lam = np.ones(k)
    jac = np.zeros((k, 2, 2))
    s = np.zeros(k)
    conv = np.zeros(k, dtype=bool)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        u, v = _tangent_basis(t)
        batch = np.concatenate([t, unit_rows(t + h * u), unit_rows(t + h * v)])
        w = eval_scaled(batch).reshape(3, k, 3)
        r = w[0] @ proj.T                              # (k, 2)
        s_now = w[0] @ d
        rn = row_norms(r)
        j_now = np.stack([(w[1] - w[0]) @ proj.T, (w[2] - w[0]) @ proj.T], axis=2) / h
        improved = rn < best_r
        # Accept improving points; for the others, halve the last step from the best point.
        best_r = np.where(improved, rn, best_r)
        best_t[improved] = t[improved]
        jac[improved] = j_now[improved]
        s[improved] = s_now[improved]
        conv = best_r <= rtol * np.maximum(np.abs(s), 1e-3)
        if np.all(conv):
            break
        step = np.zeros((k, 2))
        for_new = improved & ~conv
        if np.any(for_new):
            step_n = damped_newton_step(jac[for_new], r[for_new])
            step[for_new] = step_n
            best_step[for_new] = step_n
            bu, bv = best_uv
            bu[for_new], bv[for_new] = u[for_new], v[for_new]
            lam[for_new] = 1.0
        back = ~improved & ~conv
        lam[back] *= 0.5
        bu, bv = best_uv
        full = lam[:, None] * best_step
        t_next = unit_rows(best_t + full[:, :1] * bu + full[:, 1:] * bv)
        t = np.where(conv[:, None], best_t, t_next)
        if np.all(conv | (lam < 1e-6)):
            break
    return best_t, s, best_r, jac, conv, it
