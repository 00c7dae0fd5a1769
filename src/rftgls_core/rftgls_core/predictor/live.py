"""Live predictors: the paper's F and G solved at each state: anchor state -> capacity, slip twist.

    state (h, thetaB, thetaL1, thetaL2), pull -> posed body -> buried facets (RFT engine)
    -> W_ext(t) = -W_rft(t) - W_gravity about p -> limit surface (a registered method)
    -> capacity along d(phi) and the slip twist at the first exit.

RobotPredictor poses a robot preset (robots/), DescriptionPredictor an anchor description
(description.py) whose state variables the AnchorState feeds. Both answer with the method of
surfaces/registry.py they were built for: a surface method is fitted per state (`fit`, then
`capacity_many`); a streaming method ('direct-warm') keeps one solver per pull orientation,
warm-started from the previous state's exit (surfaces/warm.py), with the answers of its surface
method. `predict_many` and `fit` always answer with the surface method (one fit, many angles).

Scaled metric (surfaces/scaling.py): s_F = the anchor's weight, L_c = its char_length; unit slip
twists are reported in that metric too, (vx, vz, wy L_c) / norm. Fixing both per anchor keeps
the twist sample (and so the twist-sphere mesh) the same for every state of a map.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections import OrderedDict, deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..description import AnchorDescription, robot_state_map, state_values
from ..posed import pull_plane_symmetry
from ..rft.engine import BuriedBody
from ..rft.media import Medium
from ..rft.models import make_model
from ..robots.robot import G, PosedRobot, Robot
from ..surfaces.base import CapacityResult, GLSProblem, LimitSurface
from ..surfaces.registry import (
    DEFAULT_METHOD,
    default_twists,
    streaming_class,
    surface_class,
    surface_method,
)
from ..surfaces.scaling import Scaling
from ..types import AnchorState, Pull, Status


@dataclass(frozen=True)
class PosedProblem:
    """Everything computed for one state and pull orientation before a surface is fitted."""

    posed: PosedRobot
    body: BuriedBody
    problem: GLSProblem


# Streams per pull orientation, and the state distance that counts as one stream's (h m,
# theta_b, theta_l1, theta_l2, phi rad): 1 mm, 1 deg.
STREAMS = 16
STREAM_UNITS = np.array([1e-3, *([math.radians(1.0)] * 4)])


class LivePredictor:
    """What both live predictors share: fit-then-query per state, or a streaming solver.

    medium: where the anchor is. model: RFT stress law name. method: a registered method
    (surfaces/registry.py; 'twist-mesh' default, 'direct' the reference, 'direct-warm' the
    streaming direct). n_twists: sampled unit twists per state (None: 1000; 400 for direct,
    which only brackets with them). backend: RFT engine backend ('auto', 'numpy', 'numba').
    surface_options: keyword options of the surface class (of the streaming solver for a
    streaming method). Subclasses provide `problem(state, pull)`.

    A streaming predictor keeps the solver time of the last `window` calls (`stats()`).

    Streams: a caller that alternates between a few states (capacity_node's lower bound asks
    the state and the corners of its inputs' bands, each drifting on its own as the robot
    moves) would break one warm stream at every call, and each break is a cold solve (~10x a
    warm one). So each pull orientation keeps up to STREAMS streams, and a state goes to the
    stream whose last state is nearest (STREAM_UNITS: 1 mm, 1 deg; a new stream while there
    is room and none is within one unit). The warm solver's own guards decide warm or cold as
    before, so every answer stays the cold `direct` answer.
    """

    name = 'live'

    def __init__(self, medium: Medium, model: str = 'agarwal', method: str = DEFAULT_METHOD,
                 n_twists: int | None = None, backend: str = 'auto',
                 surface_options: dict | None = None, window: int = 1000):
        self.medium = medium
        self.stress_model = make_model(model, medium)
        self.method = method
        self.surface_method = surface_method(method)
        self.surface_cls = surface_class(self.surface_method)
        self.n_twists = int(n_twists if n_twists is not None else default_twists(method))
        self.backend = backend
        self.surface_options = dict(surface_options or {})
        self.streaming_cls = streaming_class(method)
        self.solvers: dict[str, Any] = {}              # pull -> its first streaming solver
        # pull -> [(state and phi in STREAM_UNITS, solver)] of its streams, first is solvers[pull]
        self._streams: dict[str, list[list[Any]]] = {}
        # the posed problems of the last states streamed, so a state asked again (at another
        # pull angle) hands its solver the same problem, whose fit it keeps
        self._problems: OrderedDict[tuple, tuple[Any, Any]] = OrderedDict()
        self.times_s: deque[float] = deque(maxlen=int(window))

    def problem(self, state: AnchorState, pull: Pull | str
                ) -> tuple[GLSProblem | None, CapacityResult | None]:
        """(the wrench map of the posed anchor, None) or (None, failure result)."""
        raise NotImplementedError

    def new_surface(self) -> LimitSurface:
        # The twist-sphere connectivity is cached per twist count, so every state reuses it.
        options = {} if self.streaming_cls is not None else self.surface_options
        return self.surface_cls(n_twists=self.n_twists, **options)

    def fit(self, state: AnchorState, pull: Pull | str) -> tuple[LimitSurface | None,
                                                                 CapacityResult | None]:
        """(fitted surface, None) or (None, failure result) for inputs with no surface."""
        problem, failure = self.problem(state, pull)
        if problem is None:
            return None, failure
        return self.new_surface().fit(problem), None

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
        if self.streaming_cls is None:
            return self.predict_many(state, [phi], pull)[0]
        t0 = time.perf_counter()
        try:
            return self._stream(state, phi, pull)
        finally:
            self.times_s.append(time.perf_counter() - t0)

    def solver(self, pull: Pull | str):
        """The streaming solver of a pull orientation (one per orientation: each stream is
        warm-started from its own previous state)."""
        key = str(getattr(pull, 'value', pull))
        if key not in self.solvers:
            assert self.streaming_cls is not None, f'{self.method} does not stream'
            self.solvers[key] = self.streaming_cls(self.n_twists, **self.surface_options)
        return self.solvers[key]

    def _nearest_solver(self, state: AnchorState, phi: float, pull: Pull | str):
        """The stream for this state (class doc): the nearest stream's solver, or a new one."""
        key = str(getattr(pull, 'value', pull))
        streams = self._streams.setdefault(key, [[None, self.solver(pull)]])
        here = np.array([*state.as_tuple(), phi]) / STREAM_UNITS
        dist = [math.inf if at is None else float(np.max(np.abs(here - at)))
                for at, _ in streams]
        k = int(np.argmin(dist))
        if dist[k] > 1.0 and streams[k][0] is not None and len(streams) < STREAMS:
            assert self.streaming_cls is not None
            streams.append([None, self.streaming_cls(self.n_twists, **self.surface_options)])
            k = len(streams) - 1
        streams[k][0] = here
        return streams[k][1]

    def _stream(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        solver = self._nearest_solver(state, phi, pull)
        key = (state.as_tuple(), str(getattr(pull, 'value', pull)))
        if key in self._problems:
            self._problems.move_to_end(key)
        else:
            self._problems[key] = self.problem(state, pull)
            if len(self._problems) > 2 * STREAMS:
                self._problems.popitem(last=False)
        problem, failure = self._problems[key]
        if problem is None:
            assert failure is not None
            solver.forget()             # the stream went where nothing is solved
            return dataclasses.replace(failure, phi=float(phi))
        return solver.solve(problem, phi)

    def stats(self) -> dict[str, float]:
        """A streaming predictor's solver figures: solve_us_median, solve_us_p99 over the
        window; steps and fallback_rate in all. Empty for a surface method."""
        if self.streaming_cls is None:
            return {}
        by_id = {id(sv): sv for sv in self.solvers.values()}
        by_id.update({id(sv): sv for streams in self._streams.values() for _, sv in streams})
        every = list(by_id.values())
        steps = sum(s.n_steps_ for s in every)
        falls = sum(s.n_fallbacks_ for s in every)
        ts = np.sort(np.asarray(self.times_s)) * 1e6
        return {'solve_us_median': float(np.median(ts)) if len(ts) else math.nan,
                'solve_us_p99': float(ts[min(len(ts) - 1, int(math.ceil(0.99 * len(ts))) - 1)])
                if len(ts) else math.nan,
                'steps': float(steps),
                'fallback_rate': falls / steps if steps else math.nan}

    def _fail(self, status: Status, reason: str, detail: str) -> CapacityResult:
        return CapacityResult(phi=math.nan, status=status, method=self.surface_method,
                              reason=reason, detail=detail)

    def _invalid_state(self, state) -> CapacityResult | None:
        if not isinstance(state, AnchorState) or not state.is_finite():
            return self._fail(Status.INVALID_INPUT, 'invalid_state',
                              f'anchor state must be finite, got {state!r}')
        return None


class RobotPredictor(LivePredictor):
    """The live predictor of a robot preset (fit-then-query per state; cheap to keep around).

    robot: the preset (robots/presets.py); the other arguments as LivePredictor.
    """

    def __init__(self, robot: Robot, medium: Medium, model: str = 'agarwal',
                 method: str = DEFAULT_METHOD, n_twists: int | None = None,
                 backend: str = 'auto', surface_options: dict | None = None):
        super().__init__(medium, model, method, n_twists, backend, surface_options)
        self.robot = robot
        self.scaling = Scaling(force_N=robot.mass * G, length_m=robot.char_length)
        self.name = f'live:{method}'

    def describe(self) -> dict:
        return {'robot': self.robot.describe(), 'medium': self.medium.to_dict(),
                'rft_model': self.stress_model.describe(), 'method': self.method,
                'n_twists': self.n_twists, 'surface_options': self.surface_options,
                'scaling': {'force_N': self.scaling.force_N,
                            'length_m': self.scaling.length_m}}

    def pose(self, state: AnchorState, pull: Pull | str) -> PosedProblem:
        posed = self.robot.pose(state, pull)
        body = BuriedBody(posed.facets, self.stress_model, ref=posed.ref,
                          mirror_y=posed.mirror_y, backend=self.backend)
        gravity = posed.gravity_wrench

        def wrench_fn(twists: np.ndarray) -> np.ndarray:
            return -body.planar_wrench(twists) - gravity

        return PosedProblem(posed, body, GLSProblem(wrench_fn, self.scaling))

    def problem(self, state: AnchorState, pull: Pull | str
                ) -> tuple[GLSProblem | None, CapacityResult | None]:
        invalid = self._invalid_state(state)
        if invalid is not None:
            return None, invalid
        outside = self.robot.state_range.violations(state)
        if outside:
            return None, self._fail(Status.OUT_OF_RANGE, 'outside_physical_range',
                                    f'not a {self.robot.name} pose: ' + '; '.join(outside))
        posed = self.pose(state, pull)
        if posed.body.facets_active == 0:
            return None, self._fail(Status.UNSUPPORTED, 'no_buried_leg',
                                    f'no leg facet is below the surface (h = {state.h:.4f} m)')
        return posed.problem, None


class DescriptionPredictor(LivePredictor):
    """The live predictor of an anchor description whose state variables the AnchorState
    feeds, with sagittal (vx, vz, wy) answers, for the consumers that speak AnchorState
    (capacity_node's live solver, the simulator ground, the lab tools). The sagittal reduction
    is used only where the posed facets pass the mirror check (posed.pull_plane_symmetry);
    elsewhere the answer is `invalid_input` `not_symmetric` (these consumers cannot carry a 6D
    twist; `rftgls capacity --anchor` can). For a shipped robot it gives RobotPredictor's
    numbers (tests/core/test_description.py).

    A description does not stream: a streaming method answers as its surface method (the
    same answers, solved afresh at every state).
    mass_scale multiplies the described mass (the simulator's heavier or lighter true robot).
    state_map: description variable -> AnchorState quantity (description.robot_state_map;
    default: the variables are named h, theta_b, theta_l1, theta_l2 or a subset of them);
    DescriptionError (one line) when the AnchorState cannot feed the description.
    """

    def __init__(self, description: AnchorDescription, medium: Medium, model: str = 'agarwal',
                 method: str | None = None, n_twists: int | None = None,
                 backend: str = 'auto', mass_scale: float = 1.0, state_map=None):
        self.state_map = robot_state_map(description, state_map)
        super().__init__(medium, model, surface_method(method or DEFAULT_METHOD), n_twists,
                         backend)
        self.description = description
        self.mass_scale = float(mass_scale)
        self.name = f'live:{self.method}:{description.name}'

    def values(self, state: AnchorState) -> dict[str, float]:
        """The description's state values (SI, by name) of an AnchorState."""
        robot = state_values(state)
        return {n: robot[q] for n, q in self.state_map.items()}

    def problem(self, state: AnchorState, pull: Pull | str
                ) -> tuple[GLSProblem | None, CapacityResult | None]:
        invalid = self._invalid_state(state)
        if invalid is not None:
            return None, invalid
        values = self.values(state)
        outside = self.description.violations(values)
        if outside:
            return None, self._fail(Status.OUT_OF_RANGE, 'outside_physical_range',
                                    f'not a {self.description.name} pose: ' + '; '.join(outside))
        posed = self.description.pose(values, pull)
        if self.mass_scale != 1.0:
            posed = dataclasses.replace(posed, mass=posed.mass * self.mass_scale)
        if len(posed.buried()) == 0:
            return None, self._fail(Status.UNSUPPORTED, 'no_buried_leg',
                                    f'no facet is below the surface (h = {state.h:.4f} m)')
        sym = pull_plane_symmetry(posed, 0.0)
        if not sym.symmetric:
            return None, self._fail(Status.INVALID_INPUT, 'not_symmetric',
                                    'sagittal answers need mirror symmetry: ' + sym.detail)
        p = np.asarray(posed.ref, dtype=float)
        body = BuriedBody(posed.facets, self.stress_model, ref=p, mirror_y=float(p[1]),
                          backend=self.backend)
        w = posed.weight
        gravity = np.array([0.0, -w, w * (posed.com[0] - p[0])])

        def wrench_fn(twists: np.ndarray) -> np.ndarray:
            return -body.planar_wrench(twists) - gravity
        scaling = Scaling(w if w > 0.0 else 1.0, posed.char_length)
        return GLSProblem(wrench_fn, scaling), None
