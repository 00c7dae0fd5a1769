"""The quasi-static simulation of a whole robot: settle on the sand, then run a gait.

Each step (docs/design/walk-burrow-physics.md):

1. The MCU's loop turns each leg's reference into a commanded rate: feed-forward plus
   kp x (reference - angle) (MiniRHex's pd_control with kd = 1), capped at the no-load speed.
2. balance.balance: the rates the servos manage and the base twist that balances every buried
   part, gravity and the tether (or: the base rests; or: no leg turns in the sand).
3. The step length: at most `dt`, a leg in or near the sand turns at most `joint_step`, the
   tether point travels at most `body_step` (and L_c x the turn as much), and no step crosses
   a corner of the gait. A requested `dt` that needs more than `max_substeps` such steps is
   too coarse for that accuracy: status invalid_input, reason step_too_coarse.
4. Explicit Euler in time for the base pose and the legs (RFT is rate independent, so the
   base moves a fixed amount per radian of leg travel and the step length is the accuracy).

Where nothing turns in the sand and the load leaves the resting parts' limit surface (the
weight at the start, a tug beyond the capacity, legs that stall) the robot slips along the
first-exit twist, in path steps of the tether point with Heun's method, exactly as
`rftgls simulate pull` (sim/trajectory.py), until the surface holds the load again. Slipping
takes no time (quasi-static).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..rft.media import Medium
from ..rft.models import make_model
from ..sim.trajectory import slip_rate
from ..types import Status
from . import balance as bal_mod
from .balance import Balance, resting_shares, scaling_of, tether_wrench
from .contact import Contact
from .energy import EnergyMeter
from .results import Sample, SimResult
from .robot import BasePose, Multibody
from .servo import XL330_M077_5V, ServoSpec
from .settle import level_depth, lowering
from .support import SlipLoad, rests


@dataclass(frozen=True)
class SimOptions:
    """dt: largest step, s. joint_step: largest turn of a leg in or near the sand per step,
    rad. body_step: largest travel of the tether point per step, m. max_substeps: steps one
    dt may be split into. slip_step: path of p per slip step, m (as `simulate pull`).
    max_slip: slip per instant after which the anchor counts as failed, m. kp: the MCU's
    position gain, 1/s. contact_depth: how deep the lowest point starts before settling, m.
    hold_model: balance.HOLD_MODELS. integrator: 'heun' or 'euler' for slips."""

    dt: float = 0.02
    joint_step: float = math.radians(1.0)
    body_step: float = 5e-4
    max_substeps: int = 64
    slip_step: float = 5e-4
    max_slip: float = 0.05
    kp: float = 3.0
    contact_depth: float = 1e-3
    hold_model: str = 'frozen'
    integrator: str = 'heun'

    def __post_init__(self) -> None:
        for key in ('dt', 'joint_step', 'body_step', 'slip_step', 'max_slip', 'contact_depth'):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f'{key} must be a positive number, got {v}')
        if not (math.isfinite(self.kp) and self.kp >= 0.0):
            raise ValueError(f'kp must be >= 0, got {self.kp}')
        if self.max_substeps < 1:
            raise ValueError('max_substeps must be >= 1')
        if self.hold_model not in bal_mod.HOLD_MODELS:
            raise ValueError(f'hold_model must be one of {", ".join(bal_mod.HOLD_MODELS)}')
        if self.integrator not in ('heun', 'euler'):
            raise ValueError("integrator must be 'heun' or 'euler'")


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
                 backend: str = 'auto'):
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
        self.frozen: dict = {}
        self.xi = np.zeros(3)
        self._hold_key: tuple | None = None
        self._last: Balance | None = None
        self.slipped_m = 0.0
        self._lower_xi: np.ndarray | None = None   # the last lowering twist, a seed

    # ------------------------------------------------------------------ placing
    def place(self, q: np.ndarray, theta_b: float = 0.0, x: float = 0.0) -> None:
        """Legs at q (rad), base pitched theta_b: lowered until its lowest point is
        contact_depth deep, then settled under its weight (a slip, no time)."""
        self.q = np.asarray(q, dtype=float).copy()
        self.pose = BasePose(x, 0.0, theta_b)
        low = self.robot.pose(self.pose, self.q).lowest_z()
        if not math.isfinite(low):
            raise SimulationStop(Status.UNSUPPORTED, 'no_contact', 'the robot has no facets')

        def held(z: float) -> bool:
            posed = self.robot.pose(BasePose(x, z, theta_b), self.q)
            contact = Contact(posed, self.model, np.zeros(len(self.q)), backend=self.backend)
            return contact.any and rests(contact.parts, -posed.gravity, scaling_of(posed))
        try:
            z = level_depth(held, -low - self.options.contact_depth)
        except ValueError as exc:
            raise SimulationStop(Status.UNSUPPORTED, 'no_support', str(exc)) from None
        self.pose = BasePose(x, z, theta_b)
        self._record('start', 'start', *self._idle())
        self.settle()

    def settle(self, tension: float = 0.0, phi: float = 0.0, phase: str = 'settle') -> bool:
        """Slip until the resting robot holds its weight and the tether; True when it holds
        (False: still slipping after max_slip)."""
        return self._slip(tension, phi, phase)

    # ------------------------------------------------------------------ stepping
    def run(self, gait, progress=None) -> SimResult:
        """Place the robot at the gait's start, settle, run the gait to its end."""
        t0 = time.perf_counter()
        result = self._result(gait)
        try:
            self.place(gait.start())
            knots = sorted(set(gait.knots()) | {gait.duration})
            while self.t < gait.duration - 1e-12:
                nxt = min(k for k in knots if k > self.t + 1e-12)
                dt = min(self.options.dt, nxt - self.t)
                self.step(dt, gait)
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
        for _ in range(self.options.max_substeps):
            if self.t >= end - 1e-12:
                return
            q_ref, ff = gait.reference(self.t)
            tension, phi = gait.tether(self.t)
            self._substep(end - self.t, q_ref, ff, tension, phi, gait.phase(self.t))
        if self.t < end - 1e-12:
            raise SimulationStop(
                Status.INVALID_INPUT, 'step_too_coarse',
                f'time step {dt:.4g} s needs more than {self.options.max_substeps} steps to keep '
                f'legs within {math.degrees(self.options.joint_step):.3g} deg and the body '
                f'within {self.options.body_step * 1e3:.3g} mm per step (t = {self.t:.3f} s); '
                'use a smaller dt')

    def _substep(self, dt_max: float, q_ref, ff, tension: float, phi: float,
                 phase: str) -> None:
        opt = self.options
        cmd = np.asarray(ff, dtype=float) + opt.kp * (np.asarray(q_ref) - self.q)
        cmd = np.clip(cmd, -self.servo.no_load_speed, self.servo.no_load_speed)
        posed = self.robot.pose(self.pose, self.q)
        load = posed.gravity + tether_wrench(tension, phi)
        b = bal_mod.balance(posed, self.model, self.servo, cmd, load, self.frozen, self.xi,
                            opt.hold_model, self.backend)
        if b.mode == 'no_root':
            self._slide(dt_max, posed, cmd, tension, phi, phase, b.detail)
            return
        if b.mode == 'no_contact':
            raise SimulationStop(Status.UNSUPPORTED, 'no_contact',
                                 f'{b.detail} at t = {self.t:.3f} s: no leg in contact')
        if b.mode == 'hold':
            b = self._hold(b, posed, load, tension, phi, phase)
        dt = self._step_length(dt_max, posed, b)
        self._remember(b)
        self.xi = b.xi if b.mode == 'move' else np.zeros(3)
        power = self.meter.add(phase, b.torques, b.rates, b.stalled, dt)
        self.pose = self.pose.moved(b.xi, posed.ref, dt)
        self.q = self.q + b.rates * dt
        self.t += dt
        self._record(phase, b.mode, b.rates, b.torques, b.stalled, power, b.residual, b.bridge)
        self._last = b

    def _slide(self, dt_max: float, posed, cmd, tension: float, phi: float, phase: str,
               why: str) -> None:
        """No finite base twist balances the turning legs: the robot sits on the edge of its
        support and any turn of the legs that weakens it makes the base slip, faster than the
        legs turn (RFT's balance has its root at infinity). In the limit the legs hardly move
        relative to the sliding base, so the step is split: the legs turn by their step with
        the base held, then the robot slips, legs held, until the sand holds it again (the
        trajectory method). Servo torques are the legs' shares at that slip (the sand they
        are loaded with); a leg whose last share exceeded its servo's line does not turn."""
        last = self._last
        rates = np.asarray(cmd, dtype=float).copy()
        stalled = np.zeros(len(rates), bool)
        if last is not None and last.mode == 'slide':
            for i, c in enumerate(rates):
                tau = last.torques[i]
                if c != 0.0 and tau * c > 0.0 and abs(tau) > self.servo.torque_limit(c):
                    slow = self.servo.speed_at(tau)
                    rates[i] = math.copysign(min(abs(c), slow), c)
                    stalled[i] = slow < bal_mod.MIN_FRACTION * abs(c)
                    if stalled[i]:
                        rates[i] = 0.0
        b = Balance('slide', np.zeros(3), rates, np.zeros(len(rates)), stalled,
                    np.zeros(len(rates), bool), detail=why)
        dt = self._step_length(dt_max, posed, b)
        self.q = self.q + rates * dt
        if not self._slip(tension, phi, phase, force=True):
            raise SimulationStop(Status.DEGENERATE, 'no_root',
                                 f'{why}; slipped {self.options.max_slip * 1e3:.0f} mm at '
                                 f't = {self.t:.3f} s without the sand holding the robot')
        if self._last is not None and self._last.mode == 'rest':
            b.torques = self._last.torques.copy()
        for i in np.flatnonzero(stalled):
            b.torques[i] = math.copysign(self.servo.stall_torque, cmd[i])
        b.mode = 'slide'
        self.xi = np.zeros(3)
        power = self.meter.add(phase, b.torques, b.rates, b.stalled, dt)
        self.t += dt
        self._record(phase, 'slide', b.rates, b.torques, b.stalled, power)
        self._last = b

    def _step_length(self, dt_max: float, posed, b: Balance) -> float:
        opt = self.options
        dt = dt_max
        for i, facets in enumerate(posed.legs):
            w = abs(b.rates[i])
            if w == 0.0:
                continue
            reach = self._reach(i)
            if facets.centroids[:, 2].min() < reach * w * dt_max + 1e-3:
                dt = min(dt, opt.joint_step / w)
        if b.mode == 'move':
            v = max(math.hypot(b.xi[0], b.xi[1]), abs(b.xi[2]) * self.robot.char_length)
            if v > 0.0:
                dt = min(dt, opt.body_step / v)
        return dt

    def _reach(self, i: int) -> float:
        leg = self.robot.legs[i]
        return float(np.linalg.norm(leg.facets.centroids, axis=1).max())

    def _remember(self, b: Balance) -> None:
        """The wrench each part carried: what it keeps when it stops (hold_model 'frozen')."""
        for i, w in b.leg_wrench.items():
            self.frozen[i] = w
        if b.contact is not None and any(pt.jac is None for pt in b.contact.parts):
            self.frozen['base'] = b.base_wrench
        elif 'base' in self.frozen:
            del self.frozen['base']

    # ------------------------------------------------------------------ holding and slipping
    def _hold(self, b: Balance, posed, load, tension: float, phi: float, phase: str) -> Balance:
        """No leg turns in the sand: rest if the resting parts hold the load, else slip."""
        key = (self.pose, tuple(self.q), tension, phi)
        if key != self._hold_key:
            self._slip(tension, phi, phase)
            posed = self.robot.pose(self.pose, self.q)
            load = posed.gravity + tether_wrench(tension, phi)
        contact = Contact(posed, self.model, np.zeros(len(self.q)), backend=self.backend)
        if not contact.any:
            raise SimulationStop(Status.UNSUPPORTED, 'no_contact',
                                 f'no leg in contact at t = {self.t:.3f} s')
        if key != self._hold_key or self._last is None or self._last.mode != 'rest':
            shares = resting_shares(contact, contact.parts, -load, self.frozen,
                                    scaling_of(posed), self.options.hold_model)
            rest = Balance('rest', np.zeros(3), b.rates, np.zeros(len(self.q)), b.stalled,
                           b.slowed, contact=contact)
            bal_mod._record(rest, contact, contact.parts, shares)
            self._hold_key = (self.pose, tuple(self.q), tension, phi)
        else:
            rest = replace(self._last, rates=b.rates, stalled=b.stalled, slowed=b.slowed,
                           torques=self._last.torques.copy())
        for i in np.flatnonzero(b.stalled):
            rest.torques[i] = b.torques[i]
        for i in range(len(self.q)):      # legs turning in the air carry nothing
            if b.rates[i] != 0.0:
                rest.torques[i] = 0.0
        return rest

    def _slip(self, tension: float, phi: float, phase: str, force: bool = False) -> bool:
        """Quasi-static slip with the legs held until the resting robot holds its load: under
        the weight alone a lowering (settle.py), with a tether the trajectory method's steps
        (sim/trajectory.py). The last step is shortened by bisection so the robot stops where
        it first holds. True when it holds; False (force) or SimulationStop after max_slip."""
        if tension <= 0.0:
            return self._lower(phase, force)
        opt = self.options
        travel = 0.0
        while True:
            held, res, posed = self._held(tension, phi)
            if held:
                return True
            k1 = slip_rate(res)
            if k1 is None:
                raise SimulationStop(Status.DEGENERATE, 'slip_failed',
                                     f'no slip twist at t = {self.t:.3f} s: {res.status.value} '
                                     f'{res.reason}')
            if travel >= opt.max_slip:
                return self._failed(travel, force)
            h = opt.slip_step
            start = self.pose
            delta = h * k1
            if opt.integrator == 'heun':
                self.pose = self._moved(start, posed.ref, delta)
                k2 = slip_rate(self._held(tension, phi)[1])
                if k2 is not None:
                    delta = h * 0.5 * (k1 + k2)
            self.pose = self._moved(start, posed.ref, delta)
            if self._held(tension, phi)[0]:
                hi = self._first(lambda f: self._moved(start, posed.ref, f * delta),
                                 lambda: self._held(tension, phi)[0])
                h *= hi
            travel += h
            self.slipped_m += h
            self._record(phase, 'slip', *self._idle())

    def _lower(self, phase: str, force: bool) -> bool:
        """Lower the robot as by a crane at its centre of mass until the sand carries its
        weight (settle.py); the parts' shares at the end become what they hold."""
        opt = self.options
        travel, guess = 0.0, self._lower_xi
        while True:
            posed = self.robot.pose(self.pose, self.q)
            xi, crane, shares, contact = self._lowering(posed, guess)
            self._lower_xi = xi
            if crane <= 0.0:
                self._keep_shares(contact, shares, posed)
                return True
            if travel >= opt.max_slip:
                return self._failed(travel, force)
            turn = max(math.hypot(xi[0], xi[1]), abs(xi[2]) * self.robot.char_length)
            h = min(opt.slip_step, opt.body_step / max(turn, 1e-12))
            start, guess = self.pose, xi
            self.pose = start.moved(xi, posed.ref, h)
            if self._lowering(self.robot.pose(self.pose, self.q), guess)[1] <= 0.0:
                hi = self._first(lambda f: start.moved(xi, posed.ref, f * h),
                                 lambda: self._lowering(self.robot.pose(self.pose, self.q),
                                                        guess)[1] <= 0.0)
                h *= hi
            travel += h
            self.slipped_m += h
            self._record(phase, 'slip', *self._idle())

    def _lowering(self, posed, guess):
        contact = Contact(posed, self.model, np.zeros(len(self.q)), backend=self.backend)
        if not contact.any:     # in the air: straight down
            return np.array([0.0, -1.0, 0.0]), self.robot.weight, [], contact
        xi, crane, shares, ok = lowering(contact, posed, guess)
        if not ok and guess is not None:      # the last twist led astray: scan afresh
            xi, crane, shares, ok = lowering(contact, posed, None)
        if not ok:
            raise SimulationStop(Status.DEGENERATE, 'slip_failed',
                                 f'no lowering twist balances the sand at t = {self.t:.3f} s')
        return xi, crane, shares, contact

    def _keep_shares(self, contact: Contact, shares: list, posed) -> None:
        """Shares of the settled weight, scaled to carry it exactly (Fx = 0 and no moment
        about c hold already; Fz is the weight less the crane's force, <= 0)."""
        if not shares:
            return
        fz = sum(float(w[1]) for w in shares)
        k = self.robot.weight / fz if fz > 0.0 else 1.0
        rest = Balance('rest', np.zeros(3), np.zeros(len(self.q)), np.zeros(len(self.q)),
                       np.zeros(len(self.q), bool), np.zeros(len(self.q), bool), contact=contact)
        bal_mod._record(rest, contact, contact.parts, [k * w for w in shares])
        self._remember(rest)
        self._last = rest
        self._hold_key = (self.pose, tuple(self.q), 0.0, 0.0)

    def _first(self, place, holds) -> float:
        """Shortest fraction of the last step after which the robot holds (bisection, 1/16);
        leaves the pose there."""
        lo, hi = 0.0, 1.0
        for _ in range(4):
            mid = 0.5 * (lo + hi)
            self.pose = place(mid)
            if holds():
                hi = mid
            else:
                lo = mid
        self.pose = place(hi)
        return hi

    def _failed(self, travel: float, force: bool) -> bool:
        if force:
            return False
        raise SimulationStop(Status.DEGENERATE, 'anchor_failed',
                             f'slipped {travel * 1e3:.0f} mm without holding the load '
                             f'(t = {self.t:.3f} s)')

    def _idle(self):
        n = len(self.q)
        return np.zeros(n), np.zeros(n), np.zeros(n, bool)

    @staticmethod
    def _moved(start: BasePose, ref: np.ndarray, delta: np.ndarray) -> BasePose:
        """The pose after a slip step delta = (dx, dz, d theta_b) of the tether point."""
        return start.moved(np.array([delta[0], delta[1], -delta[2]]), ref, 1.0)

    def _held(self, tension: float, phi: float):
        """(held, capacity result along the tether, posed) with the legs held."""
        posed = self.robot.pose(self.pose, self.q)
        contact = Contact(posed, self.model, np.zeros(len(self.q)), backend=self.backend)
        if not contact.any:
            raise SimulationStop(Status.UNSUPPORTED, 'no_contact',
                                 f'no part of the robot touches the sand (t = {self.t:.3f} s)')
        held, res = SlipLoad(posed.gravity, tension, phi).held(contact.parts, scaling_of(posed))
        return held, res, posed

    # ------------------------------------------------------------------ records
    def _record(self, phase: str, mode: str, rates, torques, stalled, power=None,
                residual: float = 0.0, bridge: float = 0.0) -> None:
        p = self.pose.origin + self.pose.rotation @ self.robot.tether
        n = len(self.q)
        self.samples.append(Sample(
            self.t, phase, mode, self.pose.x, self.pose.z, self.pose.theta_b, float(p[0]),
            float(p[2]), self.q.copy(), np.asarray(rates, dtype=float).copy(),
            np.asarray(torques, dtype=float).copy(),
            np.zeros(n) if power is None else np.asarray(power, dtype=float).copy(),
            np.asarray(stalled, dtype=bool).copy(), residual, bridge))

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
        return out

    def provenance(self) -> dict:
        return {'medium': self.medium.to_dict(), 'rft_model': self.model.describe(),
                'servo': self.servo.describe(), 'robot': self.robot.describe(),
                'options': {k: getattr(self.options, k) for k in
                            self.options.__dataclass_fields__}}
