"""The simulated robot's body, legs and sand: rftgls_core's whole-robot simulation
(rftgls_core/multibody, docs/design/walk-burrow-physics.md) on the simulator's own medium.

The MCU turns commands into leg references (the Buehler clock, the burrow moves, leg targets:
robot.py's servos); here the legs track them as far as their servos' torque allows against the
sand, and the base moves as the sand, gravity and the tether make it. So the burrowed pose,
the hip torques and the electrical power emerge from the gait and the medium; nothing is
copied from the paper's Table II. The medium is the simulator's truth (``--true-medium``,
``--true-medium-scale``), which the stack never sees.

Stepping: the simulator's loop calls in small steps (2 ms); they are gathered into physics
steps of `step` seconds (the simulation substeps them for accuracy). Within a physics step
each leg's reference runs on from its value at the start with the MCU's rate. The step is
10 ms, half the period at which behavior_node streams a planned burrow's leg targets: the
MCU's servos reach each new target at their speed limit within a few ms and then rest, so a
20 ms step ran each step's references at that moment's rate (the limit, or zero) for the whole
step, and the legs it produced were not the legs the body moved on. Measured offline (the
body driven as the node drives it, its legs recorded at 100 Hz and replayed through the
burrow simulation): the body ended 41.3 mm, 10.2 deg where its own legs replayed to
46.6 mm, 8.8 deg; at 10 ms 42.8 mm, 10.1 deg against 42.7 mm, 10.0 deg, for 8 % of a core in
a burrow (5 % at 20 ms). Most steps take
a tenth of their simulated time, some (in the demo's re-burrows) many times it: the
simulator runs the body in a worker process (physics_worker.py) so its loop keeps its period.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np


class _Hold:
    """A gait for one physics step: references q0 + ff (t - t0), stopping at their targets,
    a tether, a phase name."""

    def __init__(self, t0: float, q0, ff, target, tension: float, phi: float, phase: str):
        self.t0, self.q0, self.ff = t0, np.asarray(q0, float), np.asarray(ff, float)
        self.target = np.asarray(target, float)
        self.tension, self.phi, self.name = tension, phi, phase

    def knots(self) -> list[float]:
        """When each leg's reference reaches its target."""
        moving = self.ff != 0.0
        return sorted(self.t0 + float(d) for d in
                      (self.target[moving] - self.q0[moving]) / self.ff[moving] if d > 0.0)

    def reference(self, t: float):
        q = self.q0 + self.ff * (t - self.t0)
        past = (self.ff > 0.0) & (q >= self.target) | (self.ff < 0.0) & (q <= self.target)
        return np.where(past, self.target, q), np.where(past, 0.0, self.ff)

    def tether(self, t: float):
        return self.tension, self.phi

    def phase(self, t: float) -> str:
        return self.name


class PhysicsBody:
    """robot, anchor: the true robot (a preset, or a description YAML with the preset's four
    legs and state variables theta_l1, theta_l2); medium: preset name or medium JSON file;
    medium_scale multiplies its stress scale; mass_scale the robot's mass. step: physics step,
    s."""

    def __init__(self, robot: str = 'minirquad', anchor: str = '', medium: str = 'm90_sand',
                 medium_scale: float = 1.0, mass_scale: float = 1.0, pull: str = 'backward',
                 step: float = 0.01):
        from rftgls_core.multibody.robot import from_preset
        from rftgls_core.multibody.simulate import SimOptions, Simulator
        from rftgls_core.rft.media import load_medium
        from rftgls_core.robots.presets import get_robot
        for name, v in (('medium_scale', medium_scale), ('mass_scale', mass_scale),
                        ('step', step)):
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f'{name} must be a positive number, got {v}')
        base = load_medium(medium)
        self.medium = dataclasses.replace(
            base, name=f'{base.name} x{medium_scale:g}' if medium_scale != 1.0 else base.name,
            xi_n=base.xi_n * medium_scale, zeta=base.zeta * medium_scale)
        if anchor:
            from rftgls_core.description import load_description
            from rftgls_core.multibody.described import from_description
            mb = from_description(load_description(anchor), pull)
        else:
            mb = from_preset(get_robot(robot), pull)
        if len(mb.legs) != 4:
            raise ValueError(f'the simulated MiniRQuad has four legs; {mb.name} has '
                             f'{len(mb.legs)}')
        if mass_scale != 1.0:
            mb = dataclasses.replace(mb, mass=mb.mass * mass_scale,
                                     inertia=mb.inertia * mass_scale)
        self.robot = mb
        self.step = step
        # Coarser accuracy than the offline runs (2 deg, 1 mm per step): the plant runs in
        # real time next to the stack on two cores.
        self.sim = Simulator(mb, self.medium, options=SimOptions(
            dt=step, joint_step=math.radians(2.0), body_step=1e-3))
        self._pending = 0.0
        self.elec_W = 0.0          # mean servo power above standby over the last step, W
        self.failed = ''

    def describe(self) -> str:
        return (f'physics: {self.robot.name} ({self.robot.mass:.3f} kg) in {self.medium.name} '
                f'(xi_n {self.medium.xi_n:.3g} N/m^3)')

    def place(self, q, x_p: float = 0.0) -> None:
        """Put the robot down level with legs at q (rad) and p at x_p (m, world x), and let it
        settle."""
        from rftgls_core.multibody.simulate import SimulationStop
        self._pending = 0.0
        try:
            self.sim.place(np.asarray(q, dtype=float), x=x_p - float(self.robot.tether[0]))
        except SimulationStop as stop:
            # put down on legs it cannot stand on (it does not come to rest): it freezes
            # there, and says why once, as when a step cannot go on
            self.failed = f'{stop.reason}: {stop.detail}'

    def advance(self, dt: float, q_ref, ff, target, tension: float, phi: float,
                phase: str) -> bool:
        """Gather dt; run a physics step when `step` has gathered (references from q_ref at
        rates ff, up to target, rad). True when one ran."""
        self._pending += dt
        if self._pending < self.step or self.failed:
            return False
        run, self._pending = self._pending, 0.0
        return self.run_step(run, q_ref, ff, target, tension, phi, phase)

    def run_step(self, run: float, q_ref, ff, target, tension: float, phi: float,
                 phase: str) -> bool:
        """One physics step of `run` seconds now (advance's step; physics_worker sends its
        gathered steps here). False when the plant cannot go on (`failed` says why)."""
        if self.failed:
            return False
        from rftgls_core.multibody.simulate import SimulationStop
        e0 = self.sim.meter.total().elec_J
        try:
            self.sim.step(run, _Hold(self.sim.t, q_ref, ff, target, tension, phi, phase))
        except SimulationStop as stop:
            # The plant cannot go on (the robot falls without end, ...): it freezes where it
            # is, and says why once.
            self.failed = f'{stop.reason}: {stop.detail}'
            return False
        self.elec_W = (self.sim.meter.total().elec_J - e0) / run
        return True

    @property
    def pose(self) -> tuple[float, float, float]:
        """(x, z) of the tether point p (m) and the pitch theta_b (rad)."""
        s = self.sim
        p = s.pose.origin + s.pose.rotation @ self.robot.tether
        return float(p[0]), float(p[2]), float(s.pose.theta_b)

    @property
    def q(self) -> np.ndarray:
        return self.sim.q

    @property
    def rates(self) -> np.ndarray:
        return self.sim.last.rates if self.sim.last is not None else np.zeros(len(self.sim.q))
