"""Ellipsoid limit surface: Li and Griffiths (2004) ellipsoid-specific least squares.

Model, in the scaled wrench space: (Ws - c)^T A (Ws - c) = 1 with A symmetric positive
definite and an offset centre c (gravity and granular asymmetry shift it). Fitted to the
region of interest Fx < 0 as in the paper (docs/design/limit-surfaces.md).

LG04: rows [x^2, y^2, z^2, 2yz, 2xz, 2xy, 2x, 2y, 2z, 1], S = D^T D partitioned 6 + 4, the
constraint k J - I^2 = 1 (k = 4) written as v1^T C1 v1; the eigenvector of the unique positive
eigenvalue of C1^-1 (S11 - S12 S22^-1 S12^T) gives the quadratic part, v2 = -S22^-1 S12^T v1.
The data are centred and isotropically normalised first for conditioning (isotropic, so the
constraint keeps its meaning).

Queries are closed form: capacity is the positive root of a2 s^2 + a1 s + a0 = 0 along d, and
the slip twist is the normalised gradient ts ∝ A (Ws - c) (normality; not guaranteed for RFT).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..types import Status
from .base import CapacityResult, FitInfo, GLSProblem, LimitSurface, evaluate_wrenches
from .sampling import sample_twists


@dataclass(frozen=True)
class EllipsoidFit:
    """(Ws - c)^T A (Ws - c) = 1 in scaled coordinates; `ok` when A is positive definite."""

    A: np.ndarray | None
    centre: np.ndarray | None
    ok: bool
    reason: str = ''
    rms_residual: float = float('nan')   # RMS of sqrt(q) - 1 over the fitted points


def _lg04_coefficients(x: np.ndarray, k: float = 4.0) -> np.ndarray:
    """The 10 conic coefficients (a, b, c, f, g, h, p, q, r, d) for points (N, 3)."""
    X, Y, Z = x[:, 0], x[:, 1], x[:, 2]
    D = np.column_stack([X * X, Y * Y, Z * Z, 2 * Y * Z, 2 * X * Z, 2 * X * Y,
                         2 * X, 2 * Y, 2 * Z, np.ones_like(X)])
    S = D.T @ D
    s11, s12, s22 = S[:6, :6], S[:6, 6:], S[6:, 6:]
    c1 = np.zeros((6, 6))
    c1[:3, :3] = k / 2.0 - 1.0
    np.fill_diagonal(c1[:3, :3], -1.0)
    c1[3:, 3:] = -k * np.eye(3)
    s22_inv_s21 = np.linalg.solve(s22, s12.T)
    m = np.linalg.solve(c1, s11 - s12 @ s22_inv_s21)
    vals, vecs = np.linalg.eig(m)
    vecs = np.real(vecs)
    # The solution is the eigenvector that satisfies the constraint v^T C1 v > 0 (LG04: the
    # unique positive eigenvalue). Select it by the constraint, not by the eigenvalue: for
    # noise-free data that eigenvalue is 0 up to round-off and may come out slightly negative.
    cons = np.einsum('ji,jk,ki->i', vecs, c1, vecs) / np.einsum('ji,ji->i', vecs, vecs)
    i = int(np.argmax(cons))
    if not cons[i] > 0:
        raise np.linalg.LinAlgError('no eigenvector satisfies the ellipsoid constraint')
    v1 = vecs[:, i]
    v2 = -s22_inv_s21 @ v1
    return np.concatenate([v1, v2])


def conic_to_ellipsoid(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """(A, c, positive_definite) from conic coefficients (a, b, c, f, g, h, p, q, r, d).

    x^T Q x + 2 L^T x + d = 0 -> centre c = -Q^-1 L, A = Q / (c^T Q c - d). The arbitrary sign of
    the eigenvector cancels in A; an imaginary ellipsoid (c^T Q c - d of the wrong sign) gives
    a negative definite A and ok = False.
    """
    a, b, cc, f, g, h, p, q, r, d = v
    Q = np.array([[a, h, g], [h, b, f], [g, f, cc]])
    L = np.array([p, q, r])
    centre = -np.linalg.solve(Q, L)
    denom = centre @ Q @ centre - d
    A = Q / denom
    A = 0.5 * (A + A.T)
    ev = np.linalg.eigvalsh(A)
    return A, centre, bool(np.all(np.isfinite(ev)) and ev.min() > 0.0)


def fit_ellipsoid(points_s: np.ndarray, min_points: int = 12) -> EllipsoidFit:
    """LG04 fit of scaled points (N, 3); never raises, reports failures in the result."""
    x = np.asarray(points_s, dtype=float)
    if len(x) < min_points:
        return EllipsoidFit(None, None, False,
                            f'too few points: {len(x)} < {min_points} (9 parameters)')
    mu = x.mean(axis=0)
    y = x - mu
    sig = float(np.sqrt(np.mean(np.sum(y * y, axis=1))))
    if not sig > 0:
        return EllipsoidFit(None, None, False, 'all points coincide')
    y /= sig
    sv = np.linalg.svd(y, compute_uv=False)
    if sv[-1] < 1e-6 * sv[0]:
        return EllipsoidFit(None, None, False,
                            f'flat cloud (singular values {sv[0]:.3g} .. {sv[-1]:.3g})')
    try:
        v = _lg04_coefficients(y)
        A_n, c_n, ok = conic_to_ellipsoid(v)
    except np.linalg.LinAlgError as exc:
        return EllipsoidFit(None, None, False, f'LG04 solve failed: {exc}')
    if not ok:
        return EllipsoidFit(None, None, False, 'fitted quadric is not a real ellipsoid '
                            '(A not positive definite)')
    A = A_n / sig ** 2
    c = c_n * sig + mu
    qv = np.einsum('ij,jk,ik->i', x - c, A, x - c)
    rms = float(np.sqrt(np.mean((np.sqrt(np.maximum(qv, 0.0)) - 1.0) ** 2)))
    return EllipsoidFit(A, c, True, '', rms)


class EllipsoidSurface(LimitSurface):
    """LG04 ellipsoid in scaled coordinates. roi='fx<0' (paper) or None (all points)."""

    method = 'ellipsoid'

    def __init__(self, n_twists: int = 2000, roi: str | None = 'fx<0',
                 min_points: int = 12) -> None:
        super().__init__(n_twists)
        self.roi = roi
        self.min_points = int(min_points)
        self.model: EllipsoidFit | None = None

    def fit(self, problem: GLSProblem, n_twists: int | None = None) -> 'EllipsoidSurface':
        self.problem = problem
        if n_twists is not None:
            self.n_twists = int(n_twists)
        if self.n_twists < 4:
            return self._fail_fit(Status.DEGENERATE, 'too_few_twists',
                                  f'{self.n_twists} twists: need at least {self.min_points}')
        sample = sample_twists(problem.scaling, self.n_twists)
        w, why = evaluate_wrenches(problem, sample.raw)
        if w is None:
            return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench', why)
        return self.fit_wrenches(problem, w)

    def fit_wrenches(self, problem: GLSProblem, wrenches: np.ndarray) -> 'EllipsoidSurface':
        """Fit from a raw W_ext cloud (M, 3) (twists not needed: normality gives the twist)."""
        self.problem = problem
        ws = problem.scaling.wrench_to_scaled(np.asarray(wrenches, dtype=float))
        pts = ws[ws[:, 0] < 0.0] if self.roi == 'fx<0' else ws
        self.model = fit_ellipsoid(pts, self.min_points)
        diag = {'n_points': int(len(pts)), 'rms_residual': self.model.rms_residual}
        self.fit_info = FitInfo(diagnostics=diag)
        if not self.model.ok:
            return self._fail_fit(Status.DEGENERATE, 'ellipsoid_fit', self.model.reason)
        c = self.model.centre
        if c @ self.model.A @ c >= 1.0:
            return self._fail_fit(Status.UNSUPPORTED, 'origin_outside',
                                  'origin outside the fitted ellipsoid: the legs cannot hold '
                                  'the robot in this pose')
        self.fit_info.detail = (f'{len(pts)} points, RMS radial residual '
                                f'{self.model.rms_residual:.3g}')
        return self

    def _capacity_many(self, ph: np.ndarray) -> list[CapacityResult]:
        A, c = self.model.A, self.model.centre
        d = np.stack([self.problem.load_direction_scaled(p) for p in ph])   # (K, 3)
        a2 = np.einsum('ki,ij,kj->k', d, A, d)
        a1 = -2.0 * d @ (A @ c)
        a0 = c @ A @ c - 1.0                                   # < 0: origin inside
        s = (-a1 + np.sqrt(a1 * a1 - 4.0 * a2 * a0)) / (2.0 * a2)
        grad = (s[:, None] * d - c) @ A.T
        tw = grad / np.linalg.norm(grad, axis=1, keepdims=True)
        sf = self.problem.scaling.force_N
        return [CapacityResult.make(p, Status.OK, self.method, float(si) * sf, ti,
                                    self.problem.scaling, n_hits=1, detail=self.fit_info.detail)
                for p, si, ti in zip(ph, s, tw)]
