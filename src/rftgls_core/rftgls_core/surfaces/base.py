"""The limit-surface problem, the capacity result, and the fit-then-query interface.

Space and conventions (docs/design/architecture.md, docs/design/limit-surfaces.md):
- The surface lives in external-load wrench space W_ext = -W_rft - W_gravity, planar
  (Fx, Fz, My) in (N, N, N m) about the winch point p, world axes (x forward, z up).
- Twists are planar (vx, vz, wy) in (m/s, m/s, rad/s) at p. RFT is rate independent, so each
  twist *direction* gives one point of the surface.
- The load ray starts at the origin (zero external load) along d(phi) = pull_direction(phi)
  = (-cos phi, sin phi, 0). Capacity is the distance to the FIRST exit of that ray, in N.
- Origin outside the surface (the legs cannot hold the robot's weight): status UNSUPPORTED.

Failure is a result: `CapacityResult.capacity_N` and the slip twists are None unless the status
carries a value (ok / assumed). A first-exit distance computed despite a failed check is
kept in `unchecked_capacity_N` for diagnostics only, and `reason` says what failed.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Callable, ClassVar, Iterable, Sequence

import numpy as np

from ..types import Status, pull_direction
from .scaling import Scaling

WrenchFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class GLSProblem:
    """What every surface representation is fitted to.

    wrench_fn: raw twists (M, 3) (vx, vz, wy) -> W_ext (M, 3) (Fx, Fz, My) in N, N, N m about p.
        Vectorised, rate independent (depends on the twist direction only).
    scaling: force and length scales of the scaled spaces (see scaling.py).
    """

    wrench_fn: WrenchFn
    scaling: Scaling

    def wrenches(self, twists_raw: np.ndarray) -> np.ndarray:
        """Evaluate wrench_fn on (M, 3) raw twists; checks shape and finiteness."""
        t = np.asarray(twists_raw, dtype=float)
        w = np.asarray(self.wrench_fn(t), dtype=float)
        if w.shape != t.shape:
            raise ValueError(f'wrench_fn returned shape {w.shape} for twists of shape {t.shape}')
        return w

    def load_direction_scaled(self, phi: float) -> np.ndarray:
        """Unit load direction in the scaled wrench space; equal to d(phi) (My = 0, one s_F)."""
        return np.asarray(pull_direction(phi), dtype=float)


def _tuple3(x) -> tuple[float, float, float] | None:
    if x is None:
        return None
    a = np.asarray(x, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True)
class CapacityResult:
    """Load capacity along d(phi) and the slip twist at the first exit.

    capacity_N: first-exit distance along d(phi), N; None unless status.has_value.
    slip_twist: raw (vx, vz, wy) direction with unit Euclidean norm (see Scaling.twist_from_scaled).
    slip_twist_scaled: the same twist as a unit vector of the scaled metric (compare these).
    n_hits: distinct crossings of the ray with the surface (direct: roots found); -1 unknown.
    reason: short machine-greppable cause when status is not ok ('' when ok).
    detail: human-readable diagnostics (hits, folds, fit residuals ...).
    unchecked_capacity_N: first-exit distance even when a check failed; diagnostics only.
    """

    phi: float
    status: Status
    method: str
    capacity_N: float | None = None
    slip_twist: tuple[float, float, float] | None = None
    slip_twist_scaled: tuple[float, float, float] | None = None
    n_hits: int = -1
    reason: str = ''
    detail: str = ''
    unchecked_capacity_N: float | None = None

    @property
    def ok(self) -> bool:
        return self.status.has_value

    @classmethod
    def make(cls, phi: float, status: Status, method: str, capacity: float | None,
             twist_s=None, scaling: Scaling | None = None, n_hits: int = -1, reason: str = '',
             detail: str = '') -> 'CapacityResult':
        """Build a result, dropping every value when the status carries none."""
        raw = None
        if twist_s is not None and scaling is not None:
            raw = scaling.twist_from_scaled(np.asarray(twist_s, dtype=float))
        keep = status.has_value
        cap = None if capacity is None or not math.isfinite(capacity) else float(capacity)
        return cls(phi=float(phi), status=status, method=method,
                   capacity_N=cap if keep else None,
                   slip_twist=_tuple3(raw) if keep else None,
                   slip_twist_scaled=_tuple3(twist_s) if keep else None,
                   n_hits=int(n_hits), reason=reason, detail=detail,
                   unchecked_capacity_N=cap)


def invalid_phi_result(phi, method: str) -> CapacityResult | None:
    """INVALID_INPUT for a non-finite pull angle, else None."""
    try:
        ok = math.isfinite(float(phi))
    except (TypeError, ValueError):
        ok = False
    if ok:
        return None
    return CapacityResult(phi=float('nan'), status=Status.INVALID_INPUT, method=method,
                          reason='invalid_phi', detail=f'pull angle {phi!r} is not finite')


@dataclass
class FitInfo:
    """Per-fit state every representation reports: status of the fit itself and why."""

    status: Status = Status.OK
    reason: str = ''
    detail: str = ''
    diagnostics: dict = field(default_factory=dict)


class LimitSurface(ABC):
    """Fit-then-query interface (scikit-learn style): `fit(problem)` then `capacity(phi)`.

    A fit that fails (degenerate data, invalid wrenches) does not raise: `fit_info.status`
    records it and every later query returns that status with no value.
    """

    method: ClassVar[str] = 'base'

    def __init__(self, n_twists: int = 2000) -> None:
        self.n_twists = int(n_twists)
        self.problem: GLSProblem | None = None
        self.fit_info = FitInfo(status=Status.INVALID_INPUT, reason='not_fitted',
                                detail='call fit() first')

    @abstractmethod
    def fit(self, problem: GLSProblem, n_twists: int | None = None) -> 'LimitSurface':
        ...

    def _capacity(self, phi: float) -> CapacityResult:
        """One finite angle on a fitted surface (override this or `_capacity_many`)."""
        return self._capacity_many(np.array([phi]))[0]

    def _capacity_many(self, phis: np.ndarray) -> list[CapacityResult]:
        """Finite angles on a fitted surface; representations that vectorise override it."""
        return [self._capacity(float(p)) for p in phis]

    def capacity(self, phi: float) -> CapacityResult:
        """Capacity and slip twist for pull angle phi (rad, see types.pull_direction)."""
        bad = invalid_phi_result(phi, self.method)
        if bad is not None:
            return bad
        if not self.fit_info.status.has_value:
            return CapacityResult(phi=float(phi), status=self.fit_info.status,
                                  method=self.method, reason=self.fit_info.reason,
                                  detail=self.fit_info.detail)
        return self._capacity(float(phi))

    def capacity_many(self, phis: Iterable[float] | np.ndarray) -> list[CapacityResult]:
        """capacity() for several angles, in one vectorised query when the surface allows."""
        ph = phis_array(phis)
        if not self.fit_info.status.has_value or not np.all(np.isfinite(ph)):
            return [self.capacity(p) for p in ph]
        return self._capacity_many(ph)

    def _fail_fit(self, status: Status, reason: str, detail: str) -> 'LimitSurface':
        self.fit_info = FitInfo(status=status, reason=reason, detail=detail,
                                diagnostics=self.fit_info.diagnostics)
        return self


def evaluate_wrenches(problem: GLSProblem, twists_raw: np.ndarray
                      ) -> tuple[np.ndarray | None, str]:
    """Raw W_ext for raw twists, or (None, why) if wrench_fn gives non-finite values."""
    w = problem.wrenches(twists_raw)
    if not np.all(np.isfinite(w)):
        bad = int(np.sum(~np.all(np.isfinite(w), axis=1)))
        return None, f'wrench_fn returned non-finite values for {bad} of {len(w)} twists'
    return w, ''


def phis_array(phis: Sequence[float] | np.ndarray) -> np.ndarray:
    return np.atleast_1d(np.asarray(phis, dtype=float))
