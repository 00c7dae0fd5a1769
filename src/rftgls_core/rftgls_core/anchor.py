"""The paper's F and G for one robot in one medium: anchor state -> load capacity, slip twist.

    state (h, thetaB, thetaL1, thetaL2), pull -> posed legs -> buried facets (RFT engine)
    -> W_ext(t) = -W_rft(t) - W_gravity about p -> limit surface (one of four methods)
    -> capacity along d(phi) and the slip twist at the first exit.

Scaled metric (surfaces/scaling.py): s_F = the robot's weight, L_c = robot.char_length; unit
slip twists are reported in that metric, (vx, vz, wy L_c) / norm. Fixing both per robot keeps
the twist sample (and so the twist-sphere mesh) the same for every state of a map.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .rft.engine import BuriedBody
from .rft.media import Medium
from .rft.models import make_model
from .robots.model import G, PosedRobot, RobotModel
from .surfaces.base import CapacityResult, GLSProblem, LimitSurface
from .surfaces.registry import surface_class
from .surfaces.scaling import Scaling
from .types import AnchorState, Pull, Status

DEFAULT_METHOD = 'twist-mesh'
DEFAULT_TWISTS = 1000
# direct needs the sphere only to bracket the ray (Newton does the rest): fewer twists; the
# brute-force reference needs a dense one.
DEFAULT_TWISTS_BY_METHOD = {'direct': 400, 'brute-force': 100_000}


@dataclass(frozen=True)
class PosedAnchor:
    """Everything computed for one state and pull orientation before a surface is fitted."""

    posed: PosedRobot
    body: BuriedBody
    problem: GLSProblem


class AnchorModel:
    """Capacity and slip-twist predictor (fit-then-query per state; cheap to keep around).

    robot, medium: what is anchored where. model: RFT stress model name. method: limit
    surface representation ('twist-mesh' default; 'direct' is the reference). n_twists:
    sampled unit twists per state (default 1000; 400 for direct, which only brackets with
    them). backend: RFT engine backend ('auto', 'numpy', 'numba').
    """

    def __init__(self, robot: RobotModel, medium: Medium, model: str = 'agarwal',
                 method: str = DEFAULT_METHOD, n_twists: int | None = None,
                 backend: str = 'auto', surface_options: dict | None = None):
        self.robot = robot
        self.medium = medium
        self.stress_model = make_model(model, medium)
        self.method = method
        self.surface_cls = surface_class(method)
        if n_twists is None:
            n_twists = DEFAULT_TWISTS_BY_METHOD.get(method, DEFAULT_TWISTS)
        self.n_twists = int(n_twists)
        self.backend = backend
        self.surface_options = dict(surface_options or {})
        self.scaling = Scaling(force_N=robot.mass * G, length_m=robot.char_length)

    def describe(self) -> dict:
        return {'robot': self.robot.describe(), 'medium': self.medium.to_dict(),
                'rft_model': self.stress_model.describe(), 'method': self.method,
                'n_twists': self.n_twists, 'surface_options': self.surface_options,
                'scaling': {'force_N': self.scaling.force_N,
                                                       'length_m': self.scaling.length_m}}

    def pose(self, state: AnchorState, pull: Pull | str) -> PosedAnchor:
        posed = self.robot.pose(state, pull)
        body = BuriedBody(posed.facets, self.stress_model, ref=posed.ref,
                          mirror_y=posed.mirror_y, backend=self.backend)
        gravity = posed.gravity_wrench

        def wrench_fn(twists: np.ndarray) -> np.ndarray:
            return -body.planar_wrench(twists) - gravity

        return PosedAnchor(posed, body, GLSProblem(wrench_fn, self.scaling))

    def new_surface(self) -> LimitSurface:
        # The twist-sphere connectivity is cached per twist count, so every state reuses it.
        return self.surface_cls(n_twists=self.n_twists, **self.surface_options)

    def fit(self, state: AnchorState, pull: Pull | str) -> tuple[LimitSurface | None,
                                                                 CapacityResult | None]:
        """(fitted surface, None) or (None, failure result) for inputs with no surface."""
        if not isinstance(state, AnchorState) or not state.is_finite():
            return None, self._fail(Status.INVALID_INPUT, 'invalid_state',
                                    f'anchor state must be finite, got {state!r}')
        outside = self.robot.state_range.violations(state)
        if outside:
            return None, self._fail(Status.OUT_OF_RANGE, 'outside_physical_range',
                                    f'not a {self.robot.name} pose: ' + '; '.join(outside))
        anchor = self.pose(state, pull)
        if anchor.body.facets_active == 0:
            return None, self._fail(Status.UNSUPPORTED, 'no_buried_leg',
                                    f'no leg facet is below the surface (h = {state.h:.4f} m)')
        return self.new_surface().fit(anchor.problem), None

    def predict_many(self, state: AnchorState, phis, pull: Pull | str) -> list[CapacityResult]:
        """Capacity and slip twist for several pull angles (rad) of one state."""
        return self.answers(*self.fit(state, pull), phis)

    @staticmethod
    def answers(surface: LimitSurface | None, failure: CapacityResult | None,
                phis) -> list[CapacityResult]:
        """The answers of a `fit` at pull angles phis (rad): the surface's, or the failure's."""
        phis = np.atleast_1d(np.asarray(phis, dtype=float))
        if surface is None:
            assert failure is not None
            return [CapacityResult(**{**failure.__dict__, 'phi': float(p)}) for p in phis]
        return surface.capacity_many(phis)

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.predict_many(state, [phi], pull)[0]

    def _fail(self, status: Status, reason: str, detail: str) -> CapacityResult:
        return CapacityResult(phi=math.nan, status=status, method=self.method, reason=reason,
                              detail=detail)
