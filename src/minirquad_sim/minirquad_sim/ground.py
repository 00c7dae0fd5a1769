"""The ground as the simulator sees it: anchor capacity and slip direction for a pose.

``LiveGround`` (default) is the simulator's own truth: the live RFT-GLS solver of
rftgls_core (``direct``, the reference method) on a settable "true" robot and medium, by
default the stack's preset (MiniRQuad in M90 sand) and optionally scaled (``medium_scale``
0.7 = sand 30 % weaker than the stack believes). It never reads the shipped map that
capacity_node and behavior_node predict with, so a test can make the prediction wrong.
Answers are cached per quantised state (1 mm, 1 deg) so the simulator stays real time.
``MapGround`` answers from an rftgls_core state-space map (the prediction itself, ~20 us
per query). ``TableGround`` is a clearly labelled PLACEHOLDER kept for tests that want
hand-set capacities: per-mode values chosen to reproduce the paper's Fig. 10(b) outcome.

Slip twists here follow rftgls_core: (vx, vz, wy) at p in world axes, wy about +y (so the
body pitch thetaB changes by -wy per unit of travel), scaled so |(vx, vz)| = 1.
"""
from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict
from typing import NamedTuple, Protocol

from rftgls_conventions import G
from rftgls_core.types import AnchorState, Status

from .burrow import TABLE_II


class AnchorPrediction(NamedTuple):
    """capacity: largest tension T (N) the anchor holds along d(phi), None without a value.
    slip_twist_per_m: direction of motion of p when it fails, (vx, vz, wy) in world axes with
    |(vx, vz)| = 1 (wy in rad per m of travel). status: see docs/design/architecture.md#statuses."""

    capacity: float | None
    slip_twist_per_m: tuple[float, float, float]
    status: Status


class Ground(Protocol):
    """What the simulated robot asks the ground (the simulator's truth, not a prediction)."""

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        """Capacity and slip twist for anchor state ``state`` under pull angle ``phi`` (rad)."""
        ...


class TableGround:
    """PLACEHOLDER ground: capacity from the nearest Table II final pose (see module doc).

    C = C_mode * depth_factor * (1 + k_down * max(0, -phi)), where depth_factor falls
    linearly from 1 at the mode's final depth to 0 at ``h_free`` (legs pulled out), and a
    pose more than ``pose_window`` from every final pose gets body friction only
    (mu_body * m * g). The slip twist points along the pull with an upward pull-out part.
    """

    CAPACITY_N = {'DH': 4.6, 'DL': 2.6, 'SH': 2.7}   # at phi = 0, placeholder values

    def __init__(self, mass_kg: float = 0.296, mu_body: float = 0.4, h_free: float = 0.060,
                 k_down: float = 0.8, pose_window: float = math.radians(15.0)):
        self.mass_kg = mass_kg
        self.mu_body = mu_body
        self.h_free = h_free
        self.k_down = k_down
        self.pose_window = pose_window

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        if not (state.is_finite() and math.isfinite(phi)):
            return AnchorPrediction(None, (0.0, 0.0, 0.0), Status.INVALID_INPUT)
        slip = _unit_slip(phi)
        friction = self.mu_body * self.mass_kg * G
        best, dist = None, float('inf')
        for name, seq in TABLE_II.items():
            d = math.hypot(state.theta_l1 - seq.final[0], state.theta_l2 - seq.final[1])
            if d < dist:
                best, dist = name, d
        if dist > self.pose_window or state.h >= self.h_free:
            return AnchorPrediction(friction, slip, Status.OK)
        h_final = TABLE_II[best].h
        depth = min(1.0, max(0.0, (self.h_free - state.h) / (self.h_free - h_final)))
        cap = self.CAPACITY_N[best] * depth * (1.0 + self.k_down * max(0.0, -phi))
        return AnchorPrediction(max(friction, cap), slip, Status.OK)


def _unit_slip(phi: float) -> tuple[float, float, float]:
    vx, vz = -math.cos(phi), 0.35
    n = math.hypot(vx, vz)
    # Pulled backwards, the axle end pitches down: positive wy (thetaB falls).
    return (vx / n, vz / n, 2.0)


class MapGround:
    """RFT-GLS ground from an rftgls_core capacity map (backward pulls: the winch is on the
    MiniRQuad's back). The map answers out_of_range off its grid; the simulated world needs
    an answer everywhere, so its truth there is the nearest grid edge's (the state clamped
    into the grid). Where the map has no value the simulator falls back to body friction."""

    def __init__(self, path=None, pull: str = 'backward'):
        from rftgls_core.maps import CapacityMap, shipped_map_path
        self.path = str(path) if path else str(shipped_map_path('minirquad'))
        self.map = CapacityMap.load(self.path)   # an rftgls_core Predictor, with its grid axes
        self.pull = pull

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        res = self.map.predict(state, phi, self.pull)
        if res.status.value == 'out_of_range':
            ax = self.map.axes
            state = AnchorState(*(min(max(v, float(ax[n][0])), float(ax[n][-1])) for n, v in
                                  zip(('h', 'theta_b', 'theta_l1', 'theta_l2'),
                                      state.as_tuple())))
            phi = min(max(phi, float(self.map.phis[0])), float(self.map.phis[-1]))
            res = self.map.predict(state, phi, self.pull)
        if not res.status.has_value or res.slip_twist is None:
            return AnchorPrediction(None, (0.0, 0.0, 0.0), res.status)
        return AnchorPrediction(res.capacity_N, _unit_twist(res.slip_twist, phi), res.status)


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
                 fallback_method: str | None = 'twist-mesh', pull: str = 'backward',
                 h_step: float = 1e-3, angle_step: float = math.radians(1.0),
                 phi_step: float = math.radians(1.0), cache_size: int = 512,
                 anchor: str = ''):
        from rftgls_core.predictor.live import RobotPredictor
        from rftgls_core.rft.media import load_medium
        from rftgls_core.robots.presets import get_robot
        if not (math.isfinite(medium_scale) and medium_scale > 0.0):
            raise ValueError(f'medium_scale must be a positive number, got {medium_scale}')
        if not (math.isfinite(mass_scale) and mass_scale > 0.0):
            raise ValueError(f'mass_scale must be a positive number, got {mass_scale}')
        base = load_medium(medium)
        self.medium = dataclasses.replace(
            base, name=f'{base.name} x{medium_scale:g}' if medium_scale != 1.0 else base.name,
            xi_n=base.xi_n * medium_scale, zeta=base.zeta * medium_scale)
        body = get_robot(robot)
        self.robot = dataclasses.replace(body, mass=body.mass * mass_scale) \
            if mass_scale != 1.0 else body
        self.anchor = anchor
        if anchor:
            # An anchor description instead of the preset (same four state variables; the
            # shipped descriptions give the preset's numbers): its mass scaled the same way.
            from rftgls_core.description import load_description
            from rftgls_core.predictor.live import DescriptionPredictor
            desc = load_description(anchor)
            self.models = [DescriptionPredictor(desc, self.medium, method=m, mass_scale=mass_scale)
                           for m in dict.fromkeys((method, fallback_method)) if m]
        else:
            self.models = [RobotPredictor(self.robot, self.medium, method=method)]
            if fallback_method and fallback_method != method:
                self.models.append(RobotPredictor(self.robot, self.medium, method=fallback_method))
        self.pull = pull
        self.steps = (h_step, angle_step, phi_step)
        self.cache_size = cache_size
        self._fits: OrderedDict = OrderedDict()      # state key -> [(surface|None, failure)]
        self._answers: dict = {}                      # (state key, phi key) -> prediction
        self.fits = 0                                 # count of states fitted (for tests)

    def describe(self) -> str:
        body = f'anchor description {self.anchor}' if self.anchor else \
            f'robot {self.robot.name} ({self.robot.mass:.3f} kg)'
        return (f'live {self.models[0].method} solver, {body}, medium {self.medium.name} '
                f'(xi_n {self.medium.xi_n:.3g} N/m^3)')

    def warm_up(self) -> None:
        """Answer each Table II final pose once (JIT compilation, twist-sphere build, and the
        poses a tug starts from), so the first tug does not stall a real-time loop."""
        for seq in TABLE_II.values():
            self.predict(AnchorState(seq.h, seq.theta_b, *seq.final), 0.0)

    def _key(self, state: AnchorState) -> tuple[int, int, int, int]:
        h, a, _ = self.steps
        return (round(state.h / h), round(state.theta_b / a), round(state.theta_l1 / a),
                round(state.theta_l2 / a))

    def _fit(self, key):
        fits = self._fits.get(key)
        if fits is not None:
            self._fits.move_to_end(key)
            return fits
        h, a, _ = self.steps
        state = AnchorState(key[0] * h, key[1] * a, key[2] * a, key[3] * a)
        fits = [m.fit(state, self.pull) for m in self.models]
        self.fits += 1
        self._fits[key] = fits
        if len(self._fits) > self.cache_size:
            old, _ = self._fits.popitem(last=False)
            self._answers = {k: v for k, v in self._answers.items() if k[0] != old}
        return fits

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        if not (state.is_finite() and math.isfinite(phi)):
            return AnchorPrediction(None, (0.0, 0.0, 0.0), Status.INVALID_INPUT)
        key = self._key(state)
        pk = round(phi / self.steps[2])
        hit = self._answers.get((key, pk))
        if hit is not None:
            return hit
        phi_q = pk * self.steps[2]
        status = Status.UNSUPPORTED
        pred = None
        for surface, failure in self._fit(key):
            res = surface.capacity_many([phi_q])[0] if surface is not None else failure
            if res.status.has_value and res.capacity_N is not None \
                    and res.slip_twist is not None:
                pred = AnchorPrediction(res.capacity_N, _unit_twist(res.slip_twist, phi_q),
                                        res.status)
                break
            status = res.status
        if pred is None:
            pred = AnchorPrediction(None, (0.0, 0.0, 0.0), status)
        self._answers[(key, pk)] = pred
        return pred


def make_ground(kind: str = 'live', **options) -> Ground:
    """'live' (default: rftgls_core's live solver, options as LiveGround), 'map'
    (options: path) or 'table' (the placeholder)."""
    if kind == 'live':
        return LiveGround(**options)
    if kind == 'map':
        return MapGround(**options)
    if kind == 'table':
        return TableGround(**options)
    raise ValueError(f'unknown ground {kind!r}; known: live, map, table')


def default_ground() -> Ground:
    """The simulator's own truth: the live RFT-GLS solver on the stack's preset robot and
    medium (not the map the stack predicts with)."""
    return LiveGround()
