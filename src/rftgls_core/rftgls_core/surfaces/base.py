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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import ClassVar, Self

import numpy as np

from ..types import Status, pull_direction
from .raycast import winding_number
from .scaling import Scaling
from .twist_sphere import TwistSphere

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


# Flags a value-carrying result may carry (the capacity stands; read them before acting on the
# slip twist).
FLAGS = {
    'on_jump': 'the load ray crosses a bridged jump of the RFT map: the capacity is on the '
               'closure and the slip twist lies on a facet switching set',
    'twist_ambiguous': 'several twists give the first-exit wrench: the capacity stands, the '
                       'slip twist is one of them (see twist_spread_rad)',
    'multiple_crossings': 'the load ray crosses the surface more than once: the first exit is '
                          'the capacity',
    'folded': 'the surface folds toward the origin at the first exit',
    'support_edge': 'a map cell next to states that cannot hold the weight: those corners '
                    'counted as 0 N (conservative)',
    'edge_valued': 'a map cell next to states that cannot hold the weight, answered by the '
                   'blend of its valued corners (they carry most of the weight; maps/README.md)',
    'edge_margin': 'a map cell across the support edge, on the holding side by its interpolated '
                   'support margin: the valued corners\' blend capped by s_F x margin '
                   '(maps/README.md)',
}


def _tuple3(x) -> tuple[float, float, float] | None:
    if x is None:
        return None
    a = np.asarray(x, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True)
class CapacityResult:
    """Load capacity along d(phi) and the slip twist at the first exit.

    capacity_N: first-exit distance along d(phi), N; None unless status.has_value.
    slip_twist: the slip twist, in the one meaning it has across the stack: the direction
        (vx, vz, wy) the tether point p slips in, world axes at p, m/s, m/s, rad/s, scaled to
        unit Euclidean norm (RFT is rate independent: only the direction is known;
        Scaling.twist_from_scaled). The slip trajectories, capacity_node's estimate, diagnostics
        and query service and the `rftgls capacity` JSON carry it as it is.
    slip_twist_scaled: the same direction as a unit vector of the scaled metric (vx, vz,
        wy L_c) (compare these: the angle between two of them means the same at any L_c).
    n_hits: distinct crossings of the ray with the surface (direct: roots found); -1 unknown.
    reason: short machine-greppable cause when status is not ok ('' when ok).
    detail: human-readable diagnostics (hits, folds, fit residuals ...).
    unchecked_capacity_N: first-exit distance even when a check failed; diagnostics only.
    flags: facts about a value-carrying answer that a user may act on, from FLAGS.
    twist_spread_rad: with 'twist_ambiguous', the largest angle between candidate slip twists
        (scaled metric), rad; None otherwise.
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
    flags: tuple[str, ...] = ()
    twist_spread_rad: float | None = None

    @property
    def ok(self) -> bool:
        return self.status.has_value

    @classmethod
    def make(cls, phi: float, status: Status, method: str, capacity: float | None,
             twist_s=None, scaling: Scaling | None = None, n_hits: int = -1, reason: str = '',
             detail: str = '', flags: tuple[str, ...] = (),
             twist_spread_rad: float | None = None) -> CapacityResult:
        """Build a result, dropping every value (and flag) when the status carries none."""
        unknown = set(flags) - set(FLAGS)
        if unknown:
            raise ValueError(f'unknown result flags {sorted(unknown)}')
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
                   unchecked_capacity_N=cap, flags=tuple(flags) if keep else (),
                   twist_spread_rad=twist_spread_rad if keep else None)


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


@dataclass(frozen=True)
class FitSamples:
    """What the base class hands a method's `_fit_samples`: one evaluation of the twist sphere.

    sphere: the shared twist sphere (unit scaled twists and their outward triangulation).
    wrenches_raw: (n, 3) W_ext (Fx, Fz, My) in N, N, N m at each sphere twist, finite.
    wrenches_scaled: the same in the scaled wrench space.
    winding: winding number of the sphere mesh (vertices moved to the scaled wrenches) about
        the origin: ~1 when the weight is held, ~0 when the origin is outside.
    """

    sphere: TwistSphere
    wrenches_raw: np.ndarray
    wrenches_scaled: np.ndarray
    winding: float


class LimitSurface(ABC):
    """Fit-then-query interface (scikit-learn style): `fit(problem)` then `capacity(phi)`.

    Hyper-parameters are set in `__init__` only; `fit(problem)` never changes them. The fit is
    one template for every method (a new method provides `method`, `min_twists` and
    `_fit_samples`, plus `_capacity` or `_capacity_many`):

    1. the twist count is checked against the class's `min_twists` (DEGENERATE too_few_twists);
    2. the shared twist sphere of `n_twists` twists is evaluated in one wrench_fn call
       (INVALID_INPUT non_finite_wrench);
    3. a sampled surface with no volume defines no limit surface (DEGENERATE flat_cloud);
    4. the weight-held check: the origin must lie inside the sampled surface (winding number
       of the sphere mesh), otherwise the legs cannot hold the robot (UNSUPPORTED
       origin_outside). Methods that smooth over the cloud (alpha, ellipsoid) would otherwise
       swallow the origin, so the check is made on the samples, for every method;
    5. `_fit_samples(problem, samples)` builds the method's own representation.

    A fit that fails does not raise: `fit_info.status` records it and every later query
    returns that status with no value.
    """

    method: ClassVar[str] = 'base'
    min_twists: ClassVar[int] = 8

    def __init__(self, n_twists: int = 2000) -> None:
        self.n_twists = int(n_twists)
        self.problem: GLSProblem | None = None
        # The support check's dense sphere and scaled wrenches, when this fit evaluated them.
        self.support_samples_: tuple[TwistSphere, np.ndarray] | None = None
        # The fit's own sphere and its scaled wrenches, once evaluated and finite.
        self.cloud_: tuple[TwistSphere, np.ndarray] | None = None
        self.fit_info = FitInfo(status=Status.INVALID_INPUT, reason='not_fitted',
                                detail='call fit() first')

    # -- the fit template --------------------------------------------------------------------
    def fit(self, problem: GLSProblem) -> Self:
        """Fit to `problem`; returns self. Failures are recorded in `fit_info`, never raised."""
        self.problem = problem
        self.fit_info = FitInfo()
        self.support_samples_ = None
        self.cloud_ = None
        if self.n_twists < self.min_twists:
            return self._fail_fit(Status.DEGENERATE, 'too_few_twists',
                                  f'{self.n_twists} twists: {self.method} needs at least '
                                  f'{self.min_twists}')
        sphere = self._twist_sphere()
        w, why = evaluate_wrenches(problem, sphere.twists_raw(problem.scaling))
        if w is None:
            return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench', why)
        ws = problem.scaling.wrench_to_scaled(w)
        self.cloud_ = (sphere, ws)
        sv = np.linalg.svd(ws - ws.mean(axis=0), compute_uv=False)
        if not sv[-1] > 1e-9 * sv[0]:
            return self._fail_fit(Status.DEGENERATE, 'flat_cloud',
                                  f'the sampled wrenches are flat (singular values '
                                  f'{sv[0]:.3g} .. {sv[-1]:.3g}): no limit surface')
        wind = winding_number(ws, sphere.faces)
        self.fit_info.diagnostics.update(n_twists=sphere.n, winding_number=wind)
        if sphere.n < SUPPORT_CHECK_TWISTS and _near_origin(sphere, ws):
            # The sampled surface passes within a triangle of the origin: its chords may cut
            # off a thin sliver that holds the weight, or a fold may wrap the origin that the
            # true surface leaves outside (both seen against a 4e5-twist reference). The denser
            # sphere decides, both ways; when only it holds, the method fits on it (only such
            # edge states pay for it).
            dense = TwistSphere.build(SUPPORT_CHECK_TWISTS)
            wd, why = evaluate_wrenches(problem, dense.twists_raw(problem.scaling))
            if wd is None:
                return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench', why)
            wsd = problem.scaling.wrench_to_scaled(wd)
            self.support_samples_ = (dense, wsd)   # a method may reuse them (direct does)
            wind_d = winding_number(wsd, dense.faces)
            self.fit_info.diagnostics.update(support_check_twists=dense.n,
                                             support_check_winding=wind_d)
            if abs(wind_d) < 0.5:
                wind = wind_d                       # outside after all: unsupported below
            elif abs(wind) < 0.5:
                sphere, w, ws, wind = dense, wd, wsd, wind_d   # held: fit where it holds
        if abs(wind) < 0.5:
            return self._fail_fit(Status.UNSUPPORTED, 'origin_outside',
                                  f'origin outside the sampled limit surface (winding '
                                  f'{wind:.3f}): the legs cannot hold the robot in this pose')
        return self._fit_samples(problem, FitSamples(sphere, w, ws, wind))

    def _twist_sphere(self) -> TwistSphere:
        """The sphere this surface samples (cached per twist count, shared by every pose)."""
        return TwistSphere.build(self.n_twists)

    @abstractmethod
    def _fit_samples(self, problem: GLSProblem, samples: FitSamples) -> Self:
        """Build the method's representation from checked samples; set `fit_info`; return self."""

    # -- queries -----------------------------------------------------------------------------
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

    def _fitted_problem(self) -> GLSProblem:
        """The problem of a successful fit (queries only run after one)."""
        if self.problem is None or not self.fit_info.status.has_value:
            raise RuntimeError(f'{type(self).__name__} is not fitted')
        return self.problem

    def _fail_fit(self, status: Status, reason: str, detail: str) -> Self:
        self.fit_info = FitInfo(status=status, reason=reason, detail=detail,
                                diagnostics=self.fit_info.diagnostics)
        return self


# Twists of the denser sphere that decides the weight-held check next to the support edge.
SUPPORT_CHECK_TWISTS = 8_000


def _near_origin(sphere: TwistSphere, ws: np.ndarray) -> bool:
    """True when some sampled wrench lies within its longest mesh edge of the origin, i.e. the
    origin may sit in the sliver between the chords and the true surface."""
    e = sphere.edges
    length = np.linalg.norm(ws[e[:, 0]] - ws[e[:, 1]], axis=1)
    longest = np.zeros(len(ws))
    np.maximum.at(longest, e[:, 0], length)
    np.maximum.at(longest, e[:, 1], length)
    return bool(np.any(np.linalg.norm(ws, axis=1) < longest))


def evaluate_wrenches(problem: GLSProblem, twists_raw: np.ndarray
                      ) -> tuple[np.ndarray | None, str]:
    """Raw W_ext for raw twists, or (None, why) if wrench_fn gives non-finite values."""
    w = problem.wrenches(twists_raw)
    if not np.all(np.isfinite(w)):
        bad = int(np.sum(~np.all(np.isfinite(w), axis=1)))
        return None, f'wrench_fn returned non-finite values for {bad} of {len(w)} twists'
    return w, ''


def phis_array(phis: Iterable[float] | np.ndarray) -> np.ndarray:
    return np.atleast_1d(np.asarray(list(phis) if not isinstance(phis, np.ndarray) else phis,
                                    dtype=float))
