"""Gaits as inputs of the simulation: each leg's reference angle in time, and the tether.

A gait gives, at time t (s from its start), every leg's reference joint value (rad,
unwrapped: a walking leg turns on and on) and its rate (the feed-forward of the MCU's loop),
the tether's tension and angle, and the name of its phase (energy is summed per phase). The
servos then track the reference as far as their torque allows (simulate.py).

- BurrowGait: the paper's burrowing sequence (sec. VI-B, Fig. 2): from standing to the
  "retracting" pose, a pause, then to the "final" pose, then holding until the 8 s the paper
  measures over. Each leg slews to its target at `speed` on its own, as a position-controlled
  servo does, so a leg with less to travel arrives first (the simulated firmware's burrow:
  src/minirquad_sim). The paper gives no timing: speed 1 rad/s and a 0.5 s pause are
  assumptions (the simulated firmware's), varied in the docs.
- WalkGait: the Buehler clock MiniRHex walks with (the driver's sim models the same clock),
  one clock per leg: a slow stance arc of `sweep` centred on `down` during duty x period,
  recovery through the rest of the turn. MiniRHex's walk: period 2 s, duty 0.42, sweep 40 deg,
  down 20 deg (robomechanics/MiniRHex gait parameters). Its angle grows in the direction the
  leg turns to walk forward; here a leg walks forward when its toe moves toward -x_B under
  the hip (the sand pushes it on), i.e. theta_L decreases, so the clock runs with
  theta_L = -angle and the stance is centred on theta_L = -20 deg. WBT's MiniRQuad ambles
  (footfalls a quarter cycle apart, lateral sequence LH, LF, RH, RF) and gives no period,
  duty or sweep; those are MiniRHex's.
- Hold: legs keep their angles while the tether pulls with a given tension (a tug).
- ReplayGait: legs driven along joint values measured on the robot (a burrow as it went), so
  the pose it ended in can be simulated from what was measured rather than what was commanded.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .robot import Multibody

TWO_PI = 2.0 * math.pi
DEFAULT_BURROW_SPEED = 1.0   # rad/s, each leg's slew while burrowing (assumption)
BURROW_DWELL = 0.5           # s at the retracting pose before the final move (assumption)
BURROW_WINDOW = 8.0          # s, the paper's burrow window
# A clock with phase ph starts its stance at t = (1 - ph) x period (mod period): a larger phase
# is further ahead. Footfalls LH at 0, LF at 1/4, RH at 1/2, RF at 3/4 of a cycle (the lateral
# sequence) therefore need these phases.
AMBLE = {'LH': 0.0, 'LF': 0.75, 'RH': 0.5, 'RF': 0.25}
# The paper's burrowing sequences (Table II): retracting and final (theta_L1, theta_L2), deg.
TABLE_II_BURROWS = {'DH': ((-75.0, -50.0), (-40.0, 30.0)), 'DL': ((-75.0, -50.0), (-40.0, 0.0)),
                    'SH': ((-40.0, -20.0), (-40.0, 30.0))}


class GaitError(ValueError):
    """A gait the robot cannot run (outside a joint's range, a leg through the body, ...)."""


@dataclass(frozen=True)
class BurrowGait:
    """stand, retract, final: one joint value per degree of freedom (rad). speed: each
    degree of freedom's slew rate, rad/s. dwell: pause at the retracting pose, s. duration: s."""

    robot: Multibody
    stand: tuple[float, ...]
    retract: tuple[float, ...]
    final: tuple[float, ...]
    speed: float = DEFAULT_BURROW_SPEED
    dwell: float = BURROW_DWELL
    duration: float = BURROW_WINDOW

    def __post_init__(self) -> None:
        n = len(self.robot.dof_names)
        for name in ('stand', 'retract', 'final'):
            v = getattr(self, name)
            if len(v) != n or not all(math.isfinite(x) for x in v):
                raise GaitError(f'{name} pose needs {n} finite angles '
                                f'({", ".join(self.robot.dof_names)}), got {v}')
        if not (math.isfinite(self.speed) and self.speed > 0.0):
            raise GaitError(f'burrow speed must be a positive rate, got {self.speed}')
        if not (math.isfinite(self.dwell) and self.dwell >= 0.0):
            raise GaitError(f'dwell must be >= 0 s, got {self.dwell}')
        if not (math.isfinite(self.duration) and self.duration > 0.0):
            raise GaitError(f'duration must be positive, got {self.duration}')
        if self._moves[4] > self.duration + 1e-12:
            raise GaitError(f'the burrow needs {self._moves[4]:.2f} s at '
                            f'{math.degrees(self.speed):.1f} deg/s, more than the '
                            f'{self.duration:.2f} s window')

    @cached_property
    def _moves(self):
        """(stand, retract, final, end of the retract, end of the final stroke): the
        simulation asks at every step, and a frozen gait's answer never changes."""
        a, b, c = (np.asarray(x, dtype=float) for x in (self.stand, self.retract, self.final))
        t1 = float(np.max(np.abs(b - a))) / self.speed
        t2 = t1 + self.dwell
        t3 = t2 + float(np.max(np.abs(c - b))) / self.speed
        return a, b, c, t1, t3

    def knots(self) -> list[float]:
        a, b, c, t1, t3 = self._moves
        t2 = t1 + self.dwell
        ends = [float(v) / self.speed for v in np.abs(b - a)]
        ends += [t2 + float(v) / self.speed for v in np.abs(c - b)]
        return sorted({0.0, t1, t2, t3, *ends})

    def phase(self, t: float) -> str:
        _, _, _, t1, t3 = self._moves
        return ('retract' if t < t1 else 'dwell' if t < t1 + self.dwell else
                'final' if t < t3 else 'hold')

    def dof_reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        a, b, c, t1, t3 = self._moves
        t2 = t1 + self.dwell
        if t < t2:
            frm, to, tau = a, b, t
        else:
            frm, to, tau = b, c, t - t2
        step = to - frm
        done = np.abs(step) <= self.speed * tau
        q = np.where(done, to, frm + np.sign(step) * self.speed * tau)
        return q, np.where(done, 0.0, np.sign(step) * self.speed)

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(joint values, rates) per leg at t."""
        q, r = self.dof_reference(t)
        return self.robot.joint_values(q), self.robot.joint_values(r)

    def tether(self, t: float) -> tuple[float, float]:
        return 0.0, 0.0

    def start(self) -> np.ndarray:
        return self.robot.joint_values(self.stand)


@dataclass(frozen=True)
class WalkGait:
    """Buehler clocks per leg (module doc). period s, duty (0, 1), sweep rad, down: the
    stance centre as theta_L (rad); phases: fraction of a cycle per leg name (robot.leg_order)
    or leg index; direction +1 walks forward (theta_L falls in stance), -1 backward."""

    robot: Multibody
    duration: float = 8.0
    period: float = 2.0
    duty: float = 0.42
    sweep: float = math.radians(40.0)
    down: float = math.radians(-20.0)
    phases: dict = field(default_factory=lambda: dict(AMBLE))
    direction: int = 1

    def __post_init__(self) -> None:
        for key, lo, hi in (('period', 0.0, math.inf), ('duty', 0.0, 1.0),
                            ('sweep', 0.0, TWO_PI), ('duration', 0.0, math.inf)):
            v = getattr(self, key)
            if not (math.isfinite(v) and lo < v < hi):
                raise GaitError(f'{key} must be in ({lo:g}, {hi:g}), got {v}')
        if self.direction not in (1, -1):
            raise GaitError(f'direction must be +1 or -1, got {self.direction}')
        if len(self._phase_list()) != len(self.robot.legs):
            raise GaitError('one phase per leg')

    def _phase_list(self) -> list[float]:
        out = [0.0] * len(self.robot.legs)
        for key, ph in self.phases.items():
            i = self.robot.leg_order.get(key, key) if isinstance(key, str) else key
            if not isinstance(i, int) or not 0 <= i < len(out):
                raise GaitError(f'no leg {key!r} (legs: {", ".join(self.robot.leg_order)})')
            out[i] = float(ph) % 1.0
        return out

    def _clock(self, t: float, phase: float) -> tuple[float, float]:
        """Clock angle (grows while walking) and its rate at t."""
        cycles, tau = divmod(t / self.period + phase, 1.0)
        start = -0.5 * self.sweep
        if tau < self.duty:
            return (start + self.sweep * tau / self.duty + TWO_PI * cycles,
                    self.sweep / (self.duty * self.period))
        rate = (TWO_PI - self.sweep) / ((1.0 - self.duty) * self.period)
        return (start + self.sweep + (TWO_PI - self.sweep) * (tau - self.duty)
                / (1.0 - self.duty) + TWO_PI * cycles), rate

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        q, r = [], []
        s = -float(self.direction)
        for ph in self._phase_list():
            a, w = self._clock(t, ph)
            a0, _ = self._clock(0.0, ph)
            # unwrapped, starting within half a turn of zero
            k = round((self.down + s * a0) / TWO_PI)
            q.append(self.down + s * a - TWO_PI * k)
            r.append(s * w)
        return np.array(q), np.array(r)

    def knots(self) -> list[float]:
        out = set()
        for ph in self._phase_list():
            k = 0
            while True:
                for frac in (0.0, self.duty):
                    t = (k + frac - ph) * self.period
                    if 0.0 <= t <= self.duration:
                        out.add(t)
                if (k - ph) * self.period > self.duration:
                    break
                k += 1
        return sorted(out | {0.0})

    def phase(self, t: float) -> str:
        return 'walk'

    def tether(self, t: float) -> tuple[float, float]:
        return 0.0, 0.0

    def start(self) -> np.ndarray:
        """Standing: every leg at theta_L = 0, as MiniRHex stands before it walks (its STAND
        holds each leg at desired_theta 0); the MCU's loop then brings each leg to its clock
        the short way round (simulate.position_error). Put down with its legs already at four
        clock phases (one pointing up) the robot would start on two legs, pitched."""
        return np.zeros(len(self.robot.legs))

    def stance(self, t: float) -> np.ndarray:
        """Which legs are on their slow (stance) arc at t."""
        return np.array([divmod(t / self.period + ph, 1.0)[1] < self.duty
                         for ph in self._phase_list()])


@dataclass(frozen=True)
class HoldGait:
    """Legs held at `pose` (one value per degree of freedom, rad) while the tether pulls with
    `tension` N at `phi` rad (ramped linearly over `ramp` s)."""

    robot: Multibody
    pose: tuple[float, ...]
    tension: float
    phi: float = 0.0
    ramp: float = 0.0
    duration: float = 1.0

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        return self.robot.joint_values(self.pose), np.zeros(len(self.robot.legs))

    def knots(self) -> list[float]:
        return [0.0, self.ramp] if self.ramp > 0.0 else [0.0]

    def phase(self, t: float) -> str:
        return 'tug'

    def tether(self, t: float) -> tuple[float, float]:
        k = 1.0 if self.ramp <= 0.0 else min(1.0, t / self.ramp)
        return k * self.tension, self.phi

    def start(self) -> np.ndarray:
        return self.robot.joint_values(self.pose)


@dataclass(frozen=True)
class ReplayGait:
    """Legs driven along measured joint values. times: s from the first sample, strictly
    increasing (at least two); dofs: one row per time, one joint value per degree of freedom
    (rad). Between samples the reference is linear (its rate the segment's slope); after the
    last it holds until `duration` (s; at least the last time). Knots every `knot_s` of the
    record keep the step control on the measured motion without a step per sample."""

    robot: Multibody
    times: tuple[float, ...]
    dofs: tuple[tuple[float, ...], ...]
    duration: float
    knot_s: float = 0.1

    def __post_init__(self) -> None:
        n = len(self.robot.dof_names)
        t = np.asarray(self.times, dtype=float)
        if len(t) < 2 or len(self.dofs) != len(t):
            raise GaitError(f'a replay needs at least two samples with one row each, got '
                            f'{len(t)} times and {len(self.dofs)} rows')
        if not np.all(np.isfinite(t)) or t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise GaitError('replay times must start at 0 and increase strictly')
        q = np.asarray(self.dofs, dtype=float)
        if q.shape != (len(t), n) or not np.all(np.isfinite(q)):
            raise GaitError(f'each replay row needs {n} finite angles '
                            f'({", ".join(self.robot.dof_names)})')
        if not (math.isfinite(self.duration) and self.duration >= t[-1]):
            raise GaitError(f'replay duration {self.duration} s is shorter than the record '
                            f'({t[-1]:.2f} s)')
        if not (math.isfinite(self.knot_s) and self.knot_s > 0.0):
            raise GaitError(f'knot spacing must be positive, got {self.knot_s}')

    def dof_reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        ts, q = np.asarray(self.times), np.asarray(self.dofs, dtype=float)
        if t >= ts[-1]:
            return q[-1].copy(), np.zeros(q.shape[1])
        k = max(int(np.searchsorted(ts, t, side='right')) - 1, 0)
        w = (t - ts[k]) / (ts[k + 1] - ts[k])
        return q[k] + w * (q[k + 1] - q[k]), (q[k + 1] - q[k]) / (ts[k + 1] - ts[k])

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(joint values, rates) per leg at t."""
        q, r = self.dof_reference(t)
        return self.robot.joint_values(q), self.robot.joint_values(r)

    def knots(self) -> list[float]:
        out, last = [0.0], 0.0
        for t in self.times[1:]:
            if t - last >= self.knot_s:
                out.append(float(t))
                last = t
        return sorted({*out, float(self.times[-1])})

    def phase(self, t: float) -> str:
        return 'burrow' if t < self.times[-1] else 'hold'

    def tether(self, t: float) -> tuple[float, float]:
        return 0.0, 0.0

    def start(self) -> np.ndarray:
        return self.robot.joint_values(self.dofs[0])
