"""Parts that do not turn: the limit surface of the resting parts, the resting check, the share
each resting part carries, and the slip of a robot whose legs hold still.

At base twist xi = 0 the base and the legs that do not turn have no velocity: RFT gives them
no force, and together they can supply any wrench inside their granular limit surface (paper
sec. III-B; docs/design/limit-surfaces.md). So before solving for a moving base:

    w_need = -(W_turning(xi = 0) + W_gravity + W_tether)
    rests  <=>  w_need inside the limit surface of the resting parts.

That is the capacity solvers' support check with the offset -w_need: the origin of
W_ext(t) = -W_rest(t) + w_need lies inside the sampled surface (surfaces/base.LimitSurface.fit,
winding number, denser sphere near the edge). For any xi != 0 the resting parts switch on at
full force (a friction-like jump), so a tiny moving root is never accepted without this test.

When nothing turns and the load lies outside the surface, the robot slips quasi-statically, as
in the paper's trajectory method (sim/trajectory.py): the load stays on the limit surface and
the base moves along the slip twist at its first exit, step by step, until the surface holds
the load again. A tether load uses the same problem as `rftgls simulate pull` (gravity as the
offset, the ray along d(phi), the direct solver on 400 twists), so a tug agrees with it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..surfaces.base import CapacityResult, GLSProblem
from ..surfaces.direct import DirectSurface
from ..surfaces.scaling import Scaling
from .contact import Part

# Twists of the bracketing sphere: those of the direct solver (anchor.DEFAULT_TWISTS_BY_METHOD).
N_TWISTS = 400


@dataclass(frozen=True)
class RayProblem(GLSProblem):
    """A GLSProblem whose load ray runs along a fixed raw wrench direction (Fx, Fz, My) instead
    of a tether angle (the weight, or a resting set's share of a load)."""

    direction: tuple[float, float, float] = field(default=(0.0, -1.0, 0.0))

    def load_direction_scaled(self, phi: float) -> np.ndarray:
        d = self.scaling.wrench_to_scaled(np.asarray(self.direction, dtype=float))
        return d / np.linalg.norm(d)


def _wrench_fn(parts: list[Part], offset: np.ndarray):
    def fn(twists: np.ndarray) -> np.ndarray:
        out = np.zeros((len(twists), 3))
        for pt in parts:
            out += pt.wrenches(twists)
        return -out - offset
    return fn


def fit(parts: list[Part], offset: np.ndarray, scaling: Scaling,
        direction: np.ndarray | None = None) -> DirectSurface:
    """The direct solver fitted to W_ext(t) = -W_parts(t) - offset (parts at the base twist
    t; their joint rates are ignored: resting parts). direction: a raw load direction for
    `capacity(0.0)`; None keeps the tether angle of `capacity(phi)`."""
    fn = _wrench_fn(parts, np.asarray(offset, dtype=float))
    problem = (GLSProblem(fn, scaling) if direction is None else
               RayProblem(fn, scaling, tuple(float(v) for v in direction)))
    return DirectSurface(n_twists=N_TWISTS).fit(problem)


def rests(parts: list[Part], w_need: np.ndarray, scaling: Scaling) -> bool:
    """True when the resting parts can supply w_need (N, N, N m) without moving."""
    return fit(parts, -np.asarray(w_need, dtype=float), scaling).fit_info.status.has_value


def shares(parts: list[Part], w_need: np.ndarray, scaling: Scaling) -> list[np.ndarray] | None:
    """The wrench each resting part carries when together they supply w_need (sum exact).

    The split inside a limit surface is statically indeterminate; the one taken is the onset
    of slip under the same load: each part carries its wrench at the first-exit twist t* of
    the ray along w_need, scaled by |w_need| / |W_rest(t*)|. One part carries all of it.
    None when the ray has no exit (a load the parts could not hold)."""
    w_need = np.asarray(w_need, dtype=float)
    if len(parts) == 1:
        return [w_need.copy()]
    if not np.any(w_need):
        return [np.zeros(3) for _ in parts]
    res = fit(parts, np.zeros(3), scaling, direction=-w_need).capacity(0.0)
    if not res.status.has_value or res.slip_twist is None:
        return None
    t = np.asarray(res.slip_twist, dtype=float)[None, :]
    each = [pt.wrenches(t)[0] for pt in parts]
    total = np.sum(each, axis=0)
    k = float(total @ w_need) / float(total @ total)
    return [k * w for w in each]


@dataclass(frozen=True)
class SlipLoad:
    """A load the resting robot must hold: `dead` (raw wrench about p, always applied) and an
    `active` part along a ray, either the tether (tension_N along d(phi)) or, with no tether,
    the dead load itself (the weight: the ray along it from zero)."""

    dead: np.ndarray
    tension_N: float = 0.0
    phi: float = 0.0

    def capacity(self, parts: list[Part], scaling: Scaling) -> tuple[CapacityResult, float]:
        """(result along the active ray, the active load's size in the result's units)."""
        if self.tension_N > 0.0:
            res = fit(parts, self.dead, scaling).capacity(self.phi)
            return res, self.tension_N
        # Weight alone: the sand must supply -dead; cast along it from zero (offset 0).
        res = fit(parts, np.zeros(3), scaling, direction=self.dead).capacity(0.0)
        d = scaling.wrench_to_scaled(self.dead)
        return res, float(np.linalg.norm(d)) * scaling.force_N

    def held(self, parts: list[Part], scaling: Scaling) -> tuple[bool, CapacityResult]:
        res, size = self.capacity(parts, scaling)
        ok = res.status.has_value and res.capacity_N is not None and res.capacity_N >= size
        return ok, res


def margin(res: CapacityResult, size: float) -> float:
    """Capacity over load (>= 1 holds); nan without a value."""
    if not res.status.has_value or res.capacity_N is None or size <= 0.0:
        return math.nan
    return res.capacity_N / size
