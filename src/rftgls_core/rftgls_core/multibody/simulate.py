"""The simulation of a whole robot on sand: put it down, let it settle, then run a gait.

Each step (docs/design/walk-burrow-physics.md):

1. The MCU's loop turns each leg's reference into a commanded rate: feed-forward plus
   kp x (reference - angle) (MiniRHex's pd_control with kd = 1; the error taken the short
   way round for a leg that turns fully, as pd_control does), capped at the no-load speed.
2. balance.balance: the rates the servos manage and the base twist that balances every buried
   part, gravity, the tether and (where the robot falls) its inertia.
3. The step length: at most `dt`, a leg in or near the sand turns at most `joint_step`, the
   tether point travels at most `body_step` (and L_c x the turn as much), and no step crosses
   a corner of the gait. A requested `dt` that needs more than `max_substeps` such steps is
   too coarse for that accuracy: status invalid_input, reason step_too_coarse.
   A base pitched beyond 90 deg has overturned: status unsupported, reason overturned (its
   pose is no anchor; the samples up to there are kept).
4. Backward Euler for the base pose and the legs (the twists of the step's end).

A robot is put down level with its lowest point `contact_depth` in the sand and settles (legs
held) until it rests; the gait's clock starts then.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..rft.media import Medium
from ..rft.models import make_model
from ..types import Status
from . import balance as bal_mod
from .balance import Balance, tether_wrench
from .energy import EnergyMeter
from .results import Sample, SimResult
from .robot import BasePose, Multibody
from .servo import XL330_M077_5V, ServoSpec
from .sled import Rope, Sled

# Goal velocities below half the Dynamixel's velocity unit (0.229 rev/min = 0.024 rad/s; the
# XL330 control table) command no motion.
STILL = 0.5 * 0.229 * 2.0 * math.pi / 60.0
SETTLE_STEP = 0.01   # s, the largest step while the robot settles
# A base pitched beyond a quarter turn stands on one end or lies on its back: no gait of the
# robots here recovers from it and no anchor state describes it, so the run stops there.
OVERTURNED = 0.5 * math.pi


def position_error(robot: Multibody, q_ref, q) -> np.ndarray:
    """Reference minus angle per leg, rad, as MiniRHex's pd_controller takes it: the short
    way round the circle for a leg that turns fully (robot.Leg.limits None), so a leg held
    back more than half a turn (stalled in the sand while its clock runs on) is sent back the
    other way, not on after a reference that has lapped it; the plain difference for a leg
    with joint limits."""
    err = np.asarray(q_ref, dtype=float) - np.asarray(q, dtype=float)
    free = np.array([leg.limits is None for leg in robot.legs])
    wrapped = np.mod(err + math.pi, 2.0 * math.pi) - math.pi
    return np.where(free, wrapped, err)


@dataclass(frozen=True)
class SimOptions:
    """dt: largest step, s. joint_step: largest turn of a leg in or near the sand per step,
    rad. body_step: largest travel of the tether point per step, m. max_substeps: steps one
    dt may be split into. kp: the MCU's position gain, 1/s. creep: the speed below which a
    facet carries a fraction of its stress (the closure at rest resolved by speed), m/s.
    contact_depth: how deep the lowest point starts before settling, m. settle_time: longest
    settling, s (then status unsupported, reason no_rest)."""

    dt: float = 0.02
    joint_step: float = math.radians(1.0)
    body_step: float = 5e-4
    max_substeps: int = 256
    kp: float = 3.0
    creep: float = 1e-5
    contact_depth: float = 1e-3
    settle_time: float = 2.0

    def __post_init__(self) -> None:
        for key in ('dt', 'joint_step', 'body_step', 'creep', 'contact_depth', 'settle_time'):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f'{key} must be a positive number, got {v}')
        if not (math.isfinite(self.kp) and self.kp >= 0.0):
            raise ValueError(f'kp must be >= 0, got {self.kp}')
        if self.max_substeps < 1:
            raise ValueError('max_substeps must be >= 1')


class SimulationStop(Exception):
    """A run cannot go on: status and reason for the result."""

    def __init__(self, status: Status, reason: str, detail: str):
        super().__init__(detail)
        self.status, self.reason, self.detail = status, reason, detail


class Simulator:
    """One robot in one medium, stepped in time. `place` then `run(gait)`, or `step` by step
    (the simulated MiniRQuad drives it from its MCU's commands)."""

    def __init__(self, robot: Multibody, medium: Medium, servo: ServoSpec = XL330_M077_5V,
                 options: SimOptions | None = None, model: str = 'agarwal',
                 backend: str = 'auto', sled: Sled | None = None):
        self.robot = robot
        self.medium = medium
        self.servo = servo
        self.options = options or SimOptions()
        self.model = make_model(model, medium)
        self.backend = backend
        self.meter = EnergyMeter(servo, len(robot.legs))
        self.samples: list[Sample] = []
        self.pose = BasePose(0.0, 0.0, 0.0)
        self.q = np.zeros(len(robot.legs))
        self.t = 0.0
        self.xi = np.zeros(3)
        self.last: Balance | None = None
        self.sled = sled
        self.rope: Rope | None = None     # tied when the robot has settled (place)
        self._knots_of = None             # the gait whose corners _gait_knots holds
        self._gait_knots: list[float] = []
        # each leg's reach from its hip (m): its facets' farthest centroid
        self._reach = [float(np.linalg.norm(leg.facets.centroids, axis=1).max())
                       for leg in robot.legs]

    # ------------------------------------------------------------------ placing
    def place(self, q: np.ndarray, theta_b: float = 0.0, x: float = 0.0) -> None:
        """Legs at q (rad), base pitched theta_b, put down level with its lowest point
        contact_depth deep; it settles, legs held, until it rests."""
        self.q = np.asarray(q, dtype=float).copy()
        low = self.robot.pose(BasePose(x, 0.0, theta_b), self.q).lowest_z()
        if not math.isfinite(low):
            raise SimulationStop(Status.UNSUPPORTED, 'no_contact', 'the robot has no facets')
        self.pose = BasePose(x, -low - self.options.contact_depth, theta_b)
        self.xi = np.zeros(3)
        hold = np.zeros(len(self.q))
        t_end = self.t + self.options.settle_time
        rests = 0
        while rests < 3:
            if self.t >= t_end:
                raise SimulationStop(Status.UNSUPPORTED, 'no_rest',
                                     f'the robot does not come to rest on the sand within '
                                     f'{self.options.settle_time:g} s of being put down')
            b = self._substep(min(self.options.dt, SETTLE_STEP), self.q, hold, 0.0, 0.0,
                              'settle', book=False)
            rests = rests + 1 if b.mode == 'rest' else 0
        if self.sled is not None:
            p = self.tether_point()
            self.rope = Rope(self.sled, float(p[0]), float(p[2]))
        self.t = 0.0
        self.samples.clear()
        self._record('start', 'start', b)

    # ------------------------------------------------------------------ stepping
    def run(self, gait, progress=None) -> SimResult:
        """Place the robot at the gait's start, then run the gait to its end."""
        t0 = time.perf_counter()
        result = self._result(gait)
        try:
            self.place(gait.start())
            knots = sorted(set(gait.knots()) | {gait.duration})
            while self.t < gait.duration - 1e-12:
                nxt = min(k for k in knots if k > self.t + 1e-12)
                self.step(min(self.options.dt, nxt - self.t), gait)
                if progress:
                    progress(self.t)
        except SimulationStop as stop:
            result.status, result.reason, result.detail = stop.status, stop.reason, stop.detail
        result.samples = self.samples
        result.elapsed_s = time.perf_counter() - t0
        return result

    def step(self, dt: float, gait) -> None:
        """Advance dt seconds (substepped for accuracy) along the gait's references."""
        end = self.t + dt
        knots = [k for k in self._knots(gait) if self.t + 1e-12 < k < end - 1e-12]
        for _ in range(self.options.max_substeps):
            if self.t >= end - 1e-12:
                return
            q_ref, ff = gait.reference(self.t)
            tension, phi = gait.tether(self.t)
            # no step crosses a corner of the references (a leg reaching its target)
            nxt = min([k for k in knots if k > self.t + 1e-12] + [end])
            self._substep(nxt - self.t, q_ref, ff, tension, phi, gait.phase(self.t))
        if self.t < end - 1e-12:
            raise SimulationStop(
                Status.INVALID_INPUT, 'step_too_coarse',
                f'time step {dt:.4g} s needs more than {self.options.max_substeps} steps to keep '
                f'legs within {math.degrees(self.options.joint_step):.3g} deg and the body '
                f'within {self.options.body_step * 1e3:.3g} mm per step (t = {self.t:.3f} s); '
                'use a smaller dt (or the robot falls or slips on without stopping: a tug beyond '
                'its anchor)')

    def _knots(self, gait) -> list[float]:
        """The gait's corners, s (a gait is frozen: asked once, not at every step)."""
        if self._knots_of is not gait:
            self._knots_of, self._gait_knots = gait, list(gait.knots())
        return self._gait_knots

    def _substep(self, dt_max: float, q_ref, ff, tension: float, phi: float, phase: str,
                 book: bool = True) -> Balance:
        opt = self.options
        cmd = np.asarray(ff, dtype=float) + opt.kp * position_error(self.robot, q_ref, self.q)
        cmd = np.clip(cmd, -self.servo.no_load_speed, self.servo.no_load_speed)
        # the servo turns a goal velocity below half its unit into none: a leg that close to
        # its reference holds (and a slow tail of the position loop ends)
        cmd[np.abs(cmd) < STILL] = 0.0
        posed = self.robot.pose(self.pose, self.q)
        if self.robot.base is None and posed.surface_min_z < -opt.contact_depth:
            raise SimulationStop(Status.UNSUPPORTED, 'base_in_sand',
                                 f'the base (no mesh: nothing resists it) is '
                                 f'{-posed.surface_min_z * 1e3:.1f} mm in the sand at '
                                 f't = {self.t:.3f} s')
        load = posed.gravity + tether_wrench(tension, phi)
        if self.rope is not None:
            p = self.tether_point()
            load = load + tether_wrench(*self.rope.pull(float(p[0]), float(p[2])))
        # the step length first (from the last twist and the commands), then the balance of
        # that step; a twist that would overrun body_step shortens the step and is solved again
        dt = self._step_length(dt_max, posed, cmd, self.xi)
        packs: dict = {}           # the pose's bound parts, for every solve of this step
        # the servo-line search starts from the rates last settled on: the last step's, then
        # this step's own when it is solved again shorter (balance.balance, prior)
        prior = None if self.last is None else self.last.rates
        for _ in range(24):
            b = bal_mod.balance(posed, self.model, self.servo, cmd, load, self.xi, dt,
                                opt.creep, self.backend, packs, prior)
            if not b.converged:
                # a shorter step weighs the inertia more: the balance moves toward the last
                # twist, where a root lies for a short enough step (balance.py)
                if dt <= dt_max * 2.0 ** -16:
                    raise SimulationStop(Status.DEGENERATE, 'no_balance',
                                         f'{b.detail} at t = {self.t:.3f} s')
                dt *= 0.5
                continue
            shorter = self._step_length(dt, posed, b.rates, b.xi)
            if shorter >= dt * (1.0 - 1e-9):
                break
            dt, prior = shorter, b.rates
        if book:
            power = self.meter.add(phase, b.torques, b.rates, b.stalled, dt)
        self.pose = self.pose.moved(b.xi, posed.ref, dt)
        self.q = self.q + b.rates * dt
        self.t += dt
        self.xi = b.xi
        if book:
            self._record(phase, b.mode, b, power)
        self.last = b
        if abs(self.pose.theta_b) > OVERTURNED:
            raise SimulationStop(Status.UNSUPPORTED, 'overturned',
                                 f'the base pitched to {math.degrees(self.pose.theta_b):.0f} deg '
                                 f'at t = {self.t:.3f} s ({phase}, {b.mode})')
        return b

    def _step_length(self, dt_max: float, posed, rates: np.ndarray, xi: np.ndarray) -> float:
        opt = self.options
        dt = dt_max
        for i, low in enumerate(posed.leg_low):
            w = abs(rates[i])
            if w == 0.0:
                continue
            if low < self._reach[i] * w * dt_max + 1e-3:
                dt = min(dt, opt.joint_step / w)
        v = max(math.hypot(xi[0], xi[1]), abs(xi[2]) * self.robot.char_length)
        if v > 0.0:
            dt = min(dt, opt.body_step / v)
        return max(dt, dt_max / 2 ** 20)

    # ------------------------------------------------------------------ records
    def tether_point(self) -> np.ndarray:
        """p in world axes, m."""
        return self.pose.origin + self.pose.rotation @ self.robot.tether

    def _record(self, phase: str, mode: str, b: Balance, power=None) -> None:
        p = self.tether_point()
        n = len(self.q)
        self.samples.append(Sample(
            self.t, phase, mode, self.pose.x, self.pose.z, self.pose.theta_b, float(p[0]),
            float(p[2]), self.q.copy(), np.asarray(b.rates, dtype=float).copy(),
            np.asarray(b.torques, dtype=float).copy(),
            np.zeros(n) if power is None else np.asarray(power, dtype=float).copy(),
            np.asarray(b.stalled, dtype=bool).copy(), b.residual, b.bridge, b.inertial))

    def _result(self, gait) -> SimResult:
        r = self.robot
        return SimResult(
            robot=r.name, dof_names=r.dof_names, leg_names=tuple(leg.name for leg in r.legs),
            leg_dofs=tuple(leg.dof for leg in r.legs), duration_s=gait.duration,
            reason='assumed inputs: ' + ', '.join(self.assumed_inputs()), meter=self.meter,
            provenance=self.provenance())

    def assumed_inputs(self) -> list[str]:
        out = [f'medium {self.medium.name} (literature estimate)']
        out += [f'robot {k}' for k, v in self.robot.notes.items() if 'assum' in str(v)]
        out += [f'servo {k}' for k, v in self.servo.sources if 'assum' in v]
        if self.sled is not None:
            out += ['sled friction, distance and rope stiffness']
        return out

    def provenance(self) -> dict:
        return {'medium': self.medium.to_dict(), 'rft_model': self.model.describe(),
                'servo': self.servo.describe(), 'robot': self.robot.describe(),
                'options': {k: getattr(self.options, k) for k in
                            self.options.__dataclass_fields__},
                'sled': None if self.sled is None else self.sled.describe()}
