"""Energy of the leg servos, per phase of a gait.

Per servo and step (dt s): mechanical work tau * w * dt (the servo's output: positive while it
drives its leg through the sand, negative while the sand drives it back) and electrical energy
from the motor model (servo.ServoSpec.power) above the standby draw. The paper's burrow
energies are measured "with the idle power consumption removed" (sec. VI-B): standby (17 mA
per servo) and the MCU are that idle draw, so `elec_J` excludes it and `standby_J` reports the
servos' part separately.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .servo import ServoSpec


@dataclass
class PhaseEnergy:
    mech_J: float = 0.0
    elec_J: float = 0.0
    standby_J: float = 0.0
    time_s: float = 0.0
    stall_s: float = 0.0          # servo-seconds spent stalled

    def as_dict(self) -> dict:
        return {'energy_mech_J': self.mech_J, 'energy_elec_J': self.elec_J,
                'energy_standby_J': self.standby_J, 'time_s': self.time_s,
                'stall_servo_s': self.stall_s}


@dataclass
class EnergyMeter:
    """Accumulates per phase; `per_leg_elec_J` keeps each servo's electrical total."""

    servo: ServoSpec
    n_servos: int
    phases: dict[str, PhaseEnergy] = field(default_factory=dict)
    per_leg_elec_J: np.ndarray | None = None

    def power(self, torques, rates, stalled) -> np.ndarray:
        """Electrical power per servo above standby, W."""
        return np.array([self.servo.power(float(t), float(w), bool(s))
                         for t, w, s in zip(torques, rates, stalled)])

    def add(self, phase: str, torques, rates, stalled, dt: float) -> np.ndarray:
        """Book one step; returns the per-servo electrical power used (W)."""
        if self.per_leg_elec_J is None:
            self.per_leg_elec_J = np.zeros(self.n_servos)
        p = self.power(torques, rates, stalled)
        e = self.phases.setdefault(phase, PhaseEnergy())
        e.mech_J += float(np.dot(torques, rates)) * dt
        e.elec_J += float(p.sum()) * dt
        e.standby_J += self.n_servos * self.servo.standby_current * self.servo.voltage * dt
        e.time_s += dt
        e.stall_s += float(np.count_nonzero(stalled)) * dt
        self.per_leg_elec_J += p * dt
        return p

    def total(self) -> PhaseEnergy:
        out = PhaseEnergy()
        for e in self.phases.values():
            out.mech_J += e.mech_J
            out.elec_J += e.elec_J
            out.standby_J += e.standby_J
            out.time_s += e.time_s
            out.stall_s += e.stall_s
        return out
