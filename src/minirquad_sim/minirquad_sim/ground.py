"""The ground as the simulator sees it: anchor capacity and slip direction for a pose.

Every ground is an rftgls_core Predictor, predict(state, phi, pull) -> CapacityResult, built with
rftgls_core.predictor.build_predictor; it is the simulator's truth, not the stack's prediction.
``LiveGround`` (default) is the live RFT-GLS solver of rftgls_core (``direct``, the reference
method) on a settable "true" robot and medium, by default the stack's preset (MiniRQuad in M90
sand) and optionally scaled (``medium_scale`` 0.7 = sand 30 % weaker than the stack believes).
It never reads the shipped map that capacity_node and behavior_node predict with, so a test can
make the prediction wrong. Answers are cached per quantised state (1 mm, 1 deg) so the simulator
stays real time. ``MapGround`` answers from an rftgls_core state-space map (the prediction
itself, ~20 us per query). ``TableGround`` is a clearly labelled PLACEHOLDER kept for tests that
want hand-set capacities: per-mode values chosen to reproduce the paper's Fig. 10(b) outcome.

Slip twists follow rftgls_core: (vx, vz, wy) at p in world axes, wy about +y (so the body pitch
thetaB changes by -wy per unit of travel), a unit vector; ``slip_per_m`` rescales one so
|(vx, vz)| = 1, the motion of p per metre of travel.
"""
from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict

from rftgls_conventions import G
from rftgls_core.predictor import InputNames, Predictor, PredictorSpec, build_predictor
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull, Status

from .burrow import TABLE_II

# The simulator's option for each input of a predictor specification (errors name these).
SIM_NAMES = InputNames(map='--ground map', robot='--true-robot', description='--anchor',
                       medium='--true-medium', live_method='method', n_twists='n_twists')


def slip_per_m(result: CapacityResult) -> tuple[float, float, float]:
    """How p moves per metre of travel when the anchor fails: (vx, vz, wy) of the slip twist
    rescaled so |(vx, vz)| = 1 (world axes, wy in rad per m); (0, 0, 0) without a value."""
    if not result.status.has_value or result.slip_twist is None:
        return (0.0, 0.0, 0.0)
    return _unit_twist(result.slip_twist, result.phi)


class TableGround:
    """PLACEHOLDER ground: capacity from the nearest Table II final pose (see module doc).

    C = C_mode * depth_factor * (1 + k_down * max(0, -phi)), where depth_factor falls
    linearly from 1 at the mode's final depth to 0 at ``h_free`` (legs pulled out), and a
    pose more than ``pose_window`` from every final pose gets body friction only
    (mu_body * m * g). The slip twist points along the pull with an upward pull-out part.
    """

    CAPACITY_N = {'DH': 4.6, 'DL': 2.6, 'SH': 2.7}   # at phi = 0, placeholder values
    METHOD = 'table'

    def __init__(self, mass_kg: float = 0.296, mu_body: float = 0.4, h_free: float = 0.060,
                 k_down: float = 0.8, pose_window: float = math.radians(15.0)):
        self.mass_kg = mass_kg
        self.mu_body = mu_body
        self.h_free = h_free
        self.k_down = k_down
        self.pose_window = pose_window

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                ) -> CapacityResult:
        """The placeholder's capacity (the pull orientation is not modelled)."""
        if not (state.is_finite() and math.isfinite(phi)):
            return CapacityResult(phi=phi, status=Status.INVALID_INPUT, method=self.METHOD,
                                  reason='invalid_state')
        friction = self.mu_body * self.mass_kg * G
        best, dist = None, float('inf')
        for name, seq in TABLE_II.items():
            d = math.hypot(state.theta_l1 - seq.final[0], state.theta_l2 - seq.final[1])
            if d < dist:
                best, dist = name, d
        cap = friction
        if dist <= self.pose_window and state.h < self.h_free:
            h_final = TABLE_II[best].h
            depth = min(1.0, max(0.0, (self.h_free - state.h) / (self.h_free - h_final)))
            cap = max(friction,
                      self.CAPACITY_N[best] * depth * (1.0 + self.k_down * max(0.0, -phi)))
        vx, vz, wy = _unit_slip(phi)
        n = math.sqrt(vx * vx + vz * vz + wy * wy)
        return CapacityResult(phi=phi, status=Status.OK, method=self.METHOD, capacity_N=cap,
                              slip_twist=(vx / n, vz / n, wy / n))


def _unit_slip(phi: float) -> tuple[float, float, float]:
    vx, vz = -math.cos(phi), 0.35
    n = math.hypot(vx, vz)
    # Pulled backwards, the axle end pitches down: positive wy (thetaB falls).
    return (vx / n, vz / n, 2.0)


class MapGround:
    """RFT-GLS ground from an rftgls_core capacity map (default: the shipped MiniRQuad map).
    The map answers out_of_range off its grid; the simulated world needs an answer
    everywhere, so its truth there is the nearest grid edge's (the state clamped into the
    grid). Where the map has no value the simulator falls back to body friction."""

    def __init__(self, path=None):
        self.predictor = build_predictor(PredictorSpec(map=str(path or 'minirquad'),
                                                       robot=None), SIM_NAMES)
        self.path = str(self.predictor.path)
        self.map = self.predictor.map      # its grid axes

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                ) -> CapacityResult:
        res = self.predictor.predict(state, phi, pull)
        if res.status.value == 'out_of_range':
            ax = self.map.axes
            state = AnchorState(*(min(max(v, float(ax[n][0])), float(ax[n][-1])) for n, v in
                                  zip(('h', 'theta_b', 'theta_l1', 'theta_l2'),
                                      state.as_tuple())))
            phi = min(max(phi, float(self.map.phis[0])), float(self.map.phis[-1]))
            res = self.predictor.predict(state, phi, pull)
        return res


def _unit_twist(raw, phi: float) -> tuple[float, float, float]:
    """Raw (vx, vz, wy) rescaled so |(vx, vz)| = 1 (wy in rad per m of travel of p)."""
    vx, vz, wy = raw
    n = math.hypot(vx, vz)
    if n < 1e-9:  # pure rotation about p: move p a little along the pull instead
        return _unit_slip(phi)
    return (vx / n, vz / n, wy / n)


class LiveGround:
    """The simulator's true ground: rftgls_core's live solver on its own robot and medium.

    anchor: path of an anchor description YAML (rftgls_core.description) to use instead of
    the robot preset (it must declare h, theta_b, theta_l1, theta_l2); '' = the preset.
    robot, medium: preset names (the medium may also be a medium JSON file as written by
    ``rftgls calibrate``); medium_scale: multiplies the medium's stress scales (xi_n, zeta),
    e.g. 0.7 for sand 30 % weaker than the preset; mass_scale: multiplies the true robot's
    mass (its weight presses the legs into the sand); method: 'direct' (reference), with
    ``fallback_method`` answering the few states where it has no root (direct
    says 'degenerate' at some states that do hold). h_step (m) and angle_step (rad): the
    state grid the answers are cached on; each grid state is fitted once and every pull
    angle (phi_step grid) is asked of that fit, so a quasi-static tug costs one fit.
    """

    def __init__(self, robot: str = 'minirquad', medium: str = 'm90_sand',
                 medium_scale: float = 1.0, mass_scale: float = 1.0, method: str = 'direct',
                 fallback_method: str | None = 'twist-mesh',
                 h_step: float = 1e-3, angle_step: float = math.radians(1.0),
                 phi_step: float = math.radians(1.0), cache_size: int = 512,
                 anchor: str = ''):
        from rftgls_core.rft.media import load_medium
        if not (math.isfinite(medium_scale) and medium_scale > 0.0):
            raise ValueError(f'medium_scale must be a positive number, got {medium_scale}')
        if not (math.isfinite(mass_scale) and mass_scale > 0.0):
            raise ValueError(f'mass_scale must be a positive number, got {mass_scale}')
        base = load_medium(medium)
        self.medium = dataclasses.replace(
            base, name=f'{base.name} x{medium_scale:g}' if medium_scale != 1.0 else base.name,
            xi_n=base.xi_n * medium_scale, zeta=base.zeta * medium_scale)
        self.anchor = anchor
        # The preset or an anchor description (same four state variables; the shipped
        # descriptions give the preset's numbers), its mass scaled either way.
        spec = PredictorSpec(robot=robot, description=anchor or None, medium=self.medium,
                             mass_scale=mass_scale)
        self.predictors = [build_predictor(dataclasses.replace(spec, live_method=m), SIM_NAMES)
                           for m in dict.fromkeys((method, fallback_method)) if m]
        self.steps = (h_step, angle_step, phi_step)
        self.cache_size = cache_size
        self._fits: OrderedDict = OrderedDict()      # (state key, pull) -> [(surface, failure)]
        self._answers: dict = {}                      # (state key, pull, phi key) -> answer
        self.fits = 0                                 # count of states fitted (for tests)

    def describe(self) -> str:
        first = self.predictors[0]
        body = f'anchor description {self.anchor}' if self.anchor else \
            f'robot {first.robot.name} ({first.robot.mass:.3f} kg)'
        return (f'live {first.method} solver, {body}, medium {self.medium.name} '
                f'(xi_n {self.medium.xi_n:.3g} N/m^3)')

    def warm_up(self, pull: Pull | str = Pull.BACKWARD) -> None:
        """Answer each Table II final pose once (JIT compilation, twist-sphere build, and the
        poses a tug starts from), so the first tug does not stall a real-time loop."""
        for seq in TABLE_II.values():
            self.predict(AnchorState(seq.h, seq.theta_b, *seq.final), 0.0, pull)

    def _key(self, state: AnchorState) -> tuple[int, int, int, int]:
        h, a, _ = self.steps
        return (round(state.h / h), round(state.theta_b / a), round(state.theta_l1 / a),
                round(state.theta_l2 / a))

    def _fit(self, key, pull: str):
        fits = self._fits.get((key, pull))
        if fits is not None:
            self._fits.move_to_end((key, pull))
            return fits
        h, a, _ = self.steps
        state = AnchorState(key[0] * h, key[1] * a, key[2] * a, key[3] * a)
        fits = [p.fit(state, pull) for p in self.predictors]
        self.fits += 1
        self._fits[(key, pull)] = fits
        if len(self._fits) > self.cache_size:
            old, _ = self._fits.popitem(last=False)
            self._answers = {k: v for k, v in self._answers.items() if k[:2] != old}
        return fits

    def answer_key(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                   ) -> tuple:
        """The grid cell an answer is cached under: (state key, pull, phi key)."""
        return (self._key(state), Pull(pull).value, round(phi / self.steps[2]))

    def cached(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
               ) -> CapacityResult | None:
        """The answer for this grid cell if it was computed already, else None (no solve)."""
        return self._answers.get(self.answer_key(state, phi, pull))

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                ) -> CapacityResult:
        if not (state.is_finite() and math.isfinite(phi)):
            return CapacityResult(phi=phi, status=Status.INVALID_INPUT, method='live',
                                  reason='invalid_state')
        pull = Pull(pull).value
        key = self._key(state)
        pk = round(phi / self.steps[2])
        hit = self._answers.get((key, pull, pk))
        if hit is not None:
            return hit
        phi_q = pk * self.steps[2]
        answer = None
        for surface, failure in self._fit(key, pull):
            res = surface.capacity_many([phi_q])[0] if surface is not None else failure
            answer = res
            if res.status.has_value and res.capacity_N is not None \
                    and res.slip_twist is not None:
                break
        assert answer is not None
        self._answers[(key, pull, pk)] = answer
        return answer


def make_ground(kind: str = 'live', **options) -> Predictor:
    """'live' (default: rftgls_core's live solver, options as LiveGround), 'map'
    (options: path) or 'table' (the placeholder)."""
    if kind == 'live':
        return LiveGround(**options)
    if kind == 'map':
        return MapGround(**options)
    if kind == 'table':
        return TableGround(**options)
    raise ValueError(f'unknown ground {kind!r}; known: live, map, table')


def default_ground() -> Predictor:
    """The simulator's own truth: the live RFT-GLS solver on the stack's preset robot and
    medium (not the map the stack predicts with)."""
    return LiveGround()
