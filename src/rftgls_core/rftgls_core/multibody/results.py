"""What a simulation returns: the trajectory (one row per step), stalls, energies, the status.

Statuses follow docs/design/architecture.md: a run that finished is `assumed` (its inputs
include the medium preset, assumed geometry and the servo's unpublished no-load current; the
reason names them), and carries values; `unsupported` (no_contact), `degenerate` (no_root,
slip_failed) and `invalid_input` (step_too_coarse) carry the trajectory up to the failure for
diagnosis but no final pose, energy or distance.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..types import Status
from .energy import EnergyMeter


@dataclass(frozen=True)
class Sample:
    """One instant. t s; phase of the gait; mode: 'start', 'move', 'rest', 'hold', 'slip';
    base: origin x, z (m) and theta_b (rad); p: tether point (x, z), m; q, rates, torques,
    power (W above standby) per leg; stalled per leg; residual, bridge, inertial: N (the
    balance's imbalance, the jump its root sits on, the inertial wrench of the step; forces in
    N, moments divided by L_c: balance.py)."""

    t: float
    phase: str
    mode: str
    x: float
    z: float
    theta_b: float
    px: float
    pz: float
    q: np.ndarray
    rates: np.ndarray
    torques: np.ndarray
    power: np.ndarray
    stalled: np.ndarray
    residual: float = 0.0
    bridge: float = 0.0
    inertial: float = 0.0


@dataclass
class SimResult:
    robot: str
    dof_names: tuple[str, ...]
    leg_names: tuple[str, ...]
    leg_dofs: tuple[int, ...]
    duration_s: float
    status: Status = Status.ASSUMED
    reason: str = ''
    detail: str = ''
    samples: list[Sample] = field(default_factory=list)
    meter: EnergyMeter | None = None
    elapsed_s: float = 0.0
    provenance: dict = field(default_factory=dict)

    # -------------------------------------------------------------------- summaries
    @property
    def ok(self) -> bool:
        return self.status.has_value

    def stalls(self) -> list[dict]:
        """Stall episodes: leg name, degree of freedom, start and end time (s)."""
        out = []
        open_: dict[int, float] = {}
        for s in self.samples:
            for i, st in enumerate(s.stalled):
                if st and i not in open_:
                    open_[i] = s.t
                elif not st and i in open_:
                    out.append(self._stall(i, open_.pop(i), s.t))
        end = self.samples[-1].t if self.samples else 0.0
        out += [self._stall(i, t0, end) for i, t0 in open_.items()]
        return sorted(out, key=lambda d: (d['t_start_s'], d['leg']))

    def _stall(self, i: int, t0: float, t1: float) -> dict:
        return {'leg': self.leg_names[i], 'dof': self.dof_names[self.leg_dofs[i]],
                't_start_s': t0, 't_end_s': t1}

    def final_dofs(self) -> np.ndarray:
        """Each degree of freedom's joint value as reached at the end (rad, wrapped to
        (-pi, pi], the mean over its legs)."""
        q = self.samples[-1].q
        out = []
        for k in range(len(self.dof_names)):
            vals = [q[i] for i, d in enumerate(self.leg_dofs) if d == k]
            c = np.mean(np.cos(vals))
            s = np.mean(np.sin(vals))
            out.append(math.atan2(s, c))
        return np.array(out)

    def max_residual(self) -> float:
        return max((s.residual for s in self.samples), default=0.0)

    def max_inertial(self, phases=None) -> float:
        return max((s.inertial for s in self.samples
                    if phases is None or s.phase in phases), default=0.0)

    def summary(self) -> dict:
        """The JSON of `rftgls simulate burrow|walk` (SI names; degrees where the key says)."""
        d: dict = {'robot': self.robot, 'status': self.status.value, 'reason': self.reason,
                   'detail': self.detail}
        tail = {'stalled': self.stalls(), 'duration_s': self.duration_s,
                'elapsed_s': self.elapsed_s, 'steps': len(self.samples),
                'max_residual_N': self.max_residual(), 'max_inertial_N': self.max_inertial(),
                'provenance': self.provenance}
        if not self.ok or not self.samples:
            d.update({k: None for k in ('h_m', 'theta_b_deg', 'energy_mech_J',
                                        'energy_elec_J', 'distance_m', 'mean_speed_mps',
                                        'h_mean_m')})
            d.update(tail)
            return d
        last = self.samples[-1]
        d['h_m'] = last.z
        d['theta_b_deg'] = math.degrees(last.theta_b)
        for name, v in zip(self.dof_names, self.final_dofs()):
            d[f'{name}_deg'] = math.degrees(v)
        assert self.meter is not None
        tot = self.meter.total()
        d['energy_mech_J'] = tot.mech_J
        d['energy_elec_J'] = tot.elec_J
        d['energy_standby_J'] = tot.standby_J
        d['phases'] = {k: v.as_dict() for k, v in self.meter.phases.items()}
        first = self.samples[0]
        d['start'] = {'h_m': first.z, 'theta_b_deg': math.degrees(first.theta_b)}
        d['distance_m'] = last.px - first.px
        d['mean_speed_mps'] = d['distance_m'] / self.duration_s if self.duration_s else 0.0
        d['h_mean_m'] = time_mean([s.t for s in self.samples], [s.z for s in self.samples])
        phases = d.pop('phases')
        start = d.pop('start')
        d.update(tail)
        d['start'] = start
        d['phases'] = phases
        return d

    # ------------------------------------------------------------------------- files
    def write_csv(self, path: str | Path) -> Path:
        """The trajectory, one row per step, written atomically (safe_write)."""
        from rftgls_conventions.safe_write import write_text
        legs = self.leg_names
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(['t_s', 'phase', 'mode', 'x_m', 'h_m', 'theta_b_rad', 'p_x_m', 'p_z_m']
                   + [f'q_{n}_rad' for n in legs] + [f'rate_{n}_rad_s' for n in legs]
                   + [f'torque_{n}_Nm' for n in legs] + [f'power_{n}_W' for n in legs]
                   + [f'stalled_{n}' for n in legs]
                   + ['residual_N', 'bridge_N', 'inertial_N'])
        for s in self.samples:
            # repr of a float: the shortest text that reads back to the same number
            w.writerow([repr(float(s.t))] + [s.phase, s.mode]
                       + [repr(float(v)) for v in (s.x, s.z, s.theta_b, s.px, s.pz)]
                       + [repr(float(v)) for v in s.q]
                       + [repr(float(v)) for v in s.rates]
                       + [repr(float(v)) for v in s.torques]
                       + [repr(float(v)) for v in s.power]
                       + [int(v) for v in s.stalled]
                       + [repr(float(v)) for v in (s.residual, s.bridge, s.inertial)])
        return write_text(path, buf.getvalue())


def time_mean(t: list[float], v: list[float]) -> float:
    """Time average of a sampled signal (trapezoids); the value itself for a single sample."""
    ta, va = np.asarray(t, dtype=float), np.asarray(v, dtype=float)
    span = ta[-1] - ta[0]
    if span <= 0.0:
        return float(va.mean())
    return float(np.sum(0.5 * (va[1:] + va[:-1]) * np.diff(ta)) / span)
