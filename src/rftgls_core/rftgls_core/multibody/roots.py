"""Root of RFT's set-valued closure: F(x) = 0 for a base twist x (3 unknowns).

RFT's wrench jumps where a facet switches between trailing (no stress) and leading, and at
rest a facet may carry any fraction of its stress; at the switch the facet may carry any
fraction of its leading stress, as Coulomb friction at zero slip (docs/design/closure.md). On
a MiniRQuad leg one facet carries ~0.1-0.3 N against a 2.9 N weight, so a pointwise root often
does not exist: the balance sits on a jump.

`closure_root` solves the map with each jump ramped (evaluate.py: every value on a ramp is one
the closure allows there) with Levenberg-Marquardt (forward-difference Jacobian; the plain
Newton step first, damped ones where it fails), following the root down a schedule of ramp
widths, each stage from the last. The root is certified on the last width: |F_eps(x)| <=
`accept`. `pointwise` (|F| of the unramped map at x) and `bridge` (their difference) tell a
root on a jump (bridge ~ one facet's force) from a smooth one (bridge ~ 0). This is the
reference (and the path without numba) of affine_root.py, which runs the same steps compiled.

f may return more columns than the three it balances (K, 3 + m): they ride along and come back
at the root (`Root.extra`), so quantities read there (each part's wrench) are those of the
closure point, consistent with the balance.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# Ramp widths (in n . v_hat) the root is followed down; the last is the certificate's.
EPS_SCHEDULE = (3e-2, 1e-3)
# |F_eps| (scaled) at which a root is accepted: Newton aims at its tol; round-off in the
# forward differences of a map this steep stops it near 1e-11.
ACCEPT = 1e-9


@dataclass(frozen=True)
class Root:
    """x: the root (scaled units); residual: |F_eps(x)| at the final ramp width (scaled);
    pointwise: |F(x)| of the unramped map; bridge: |F(x) - F_eps(x)| (large on a jump);
    radius: the final ramp width eps; converged: residual <= tol; evaluations: batched calls;
    extra: the extra columns of f at the root (ramped)."""

    x: np.ndarray
    residual: float
    pointwise: float
    bridge: float
    radius: float
    converged: bool
    evaluations: int
    extra: np.ndarray


def newton(f: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, tol: float,
           fd_step: float = 1e-7, max_iter: int = 40, bound: float = np.inf
           ) -> tuple[np.ndarray, float, int]:
    """Levenberg-Marquardt on f: (K, 3) -> (K, >= 3) (batched; the first three columns are
    balanced), forward-difference Jacobian: Newton where the Jacobian is well conditioned,
    damped toward gradient steps where it is not (rate independence makes two rows nearly
    parallel when the twist barely turns). Stops when |x| exceeds `bound` (a root at
    infinity). Returns (x, |f(x)|, evaluations)."""
    x = np.asarray(x0, dtype=float).copy()
    eye = np.eye(3)

    def probe(y):
        return f(y + np.vstack([np.zeros(3), fd_step * eye]))[:, :3]
    fs = probe(x)
    calls = 1
    nf = float(np.linalg.norm(fs[0]))
    mu = 1e-6
    for _ in range(max_iter):
        if nf <= tol or float(np.linalg.norm(x)) > bound:
            break
        fx = fs[0]
        jac = (fs[1:] - fx).T / fd_step
        jtj, jtf = jac.T @ jac, jac.T @ fx
        improved = False
        for trial in range(13):
            # the plain Newton step first, then ever more damped ones
            damp = 0.0 if trial == 0 else mu
            try:
                if damp == 0.0:
                    step = -np.linalg.solve(jac, fx)
                else:
                    step = -np.linalg.solve(jtj + damp * (np.diag(np.diag(jtj)) + 1e-12 * eye),
                                            jtf)
            except np.linalg.LinAlgError:
                step = np.full(3, np.nan)
            if np.all(np.isfinite(step)):
                fs_t = probe(x + step)
                calls += 1
                nt = float(np.linalg.norm(fs_t[0]))
                if nt < nf:
                    x, fs, nf, improved = x + step, fs_t, nt, True
                    if trial:
                        mu = max(mu / 4.0, 1e-12)
                    break
            if trial:
                mu *= 8.0
        if not improved:
            break
    return x, nf, calls


def closure_root(f: Callable[[np.ndarray, float], np.ndarray], x0: np.ndarray, tol: float,
                 eps: tuple[float, ...] = EPS_SCHEDULE, accept: float = ACCEPT,
                 bound: float = np.inf) -> Root:
    """Root of RFT's closure near x0 (module doc). f(x, eps): (K, 3) -> (K, 3 + m), batched,
    the map with its jumps ramped over eps (evaluate.py); f(x, 0) the exact map.

    Newton follows the smoothed root down the schedule `eps` (aiming at `tol`); converged when
    the balanced columns are below `accept` at the last (smallest) eps. A root beyond
    `bound` (|x|) is given up at once: not converged.
    """
    x = np.asarray(x0, dtype=float)
    calls = 0
    for k, e in enumerate(eps):
        scale = max(1.0, float(np.linalg.norm(x)))
        # a wide ramp's root only seeds the next stage: solve it to a fraction of its width
        stage_tol = tol if k == len(eps) - 1 else max(tol, 1e-2 * e)

        def stage(y: np.ndarray, e: float = e) -> np.ndarray:
            return f(y, e)
        x, nf, c = newton(stage, x, stage_tol,
                          fd_step=min(1e-7, 1e-3 * e) * scale, bound=bound)
        calls += c
        if float(np.linalg.norm(x)) > bound:
            last = f(x[None, :], e)[0]
            return Root(x, float(np.linalg.norm(last[:3])), np.inf, np.inf, e, False, calls + 1,
                        last[3:])
    last = f(x[None, :], eps[-1])[0]
    exact = f(x[None, :], 0.0)[0]
    res = float(np.linalg.norm(last[:3]))
    return Root(x, res, float(np.linalg.norm(exact[:3])),
                float(np.linalg.norm(exact[:3] - last[:3])), eps[-1], bool(res <= accept),
                calls + 2, last[3:])
