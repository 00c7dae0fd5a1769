"""Closed loop without ROS for the behaviour tests: the simulator's robot model (SimRobot, the
same physics minirquad_sim runs) stepped in-process, with commands applied directly and the
observation capacity_node would give built each step from the stack's predictor (the map;
an rftgls_core Predictor, asked for backward pulls).

``capacity_fault(plant) -> None | (capacity, status, assumed_inputs)`` replaces what
capacity_node says from then on (a status with its value, NaN for none); ``dead`` freezes the
estimate's receipt time (capacity_node killed: no more messages). ``estimate_height(plant)
-> h`` is the height capacity_node computes at (default: the one behavior_node sent last).
"""
from __future__ import annotations

import math

from rftgls_core.types import AnchorState
from rftgls_ros.behavior import BehaviorConfig, BehaviorMachine, ModeChooser, Observation
from rftgls_ros.capacity.range_bound import range_minimum


class Plant:
    def __init__(self, sled_mass: float, predictor, heavier_at: float | None = None,
                 heavier_mass: float = 0.0, ground=None, gait_poses=None):
        from minirquad_driver.gaits import GAITS
        from minirquad_driver.protocol.messages import BurrowMode
        from minirquad_sim.robot import SimRobot
        from minirquad_sim.winch import WinchSled
        self.gaits, self.burrow_modes = GAITS, BurrowMode
        kw = {'ground': ground} if ground is not None else {}
        self.robot = SimRobot(winch=WinchSled(sled_mass=sled_mass), gait_poses=gait_poses, **kw)
        self.predictor = predictor
        self.t = 0.0
        self.energy = 0.0
        self.slip = 0.0          # m p moved while the rope pulled it (also dragged walking)
        self.tug_slip = 0.0      # m of that while the winch reeled in
        self.heavier_at, self.heavier_mass = heavier_at, heavier_mass
        self.link_ok = True
        self.dead = False
        self.capacity_fault = None
        self.estimate_height = None
        self.h, self.phi, self.h_band = 0.06, 0.0, math.nan
        self.t_capacity = -float('inf')
        self.winch_cmd = 0.0

    def apply(self, cmd) -> None:
        r = self.robot
        for topic, value in cmd.oneshots:
            if topic == 'gait':
                g = self.gaits[value]
                r.set_gait(g.kind, g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
            else:
                r.burrow(int(getattr(self.burrow_modes, value)))
        if cmd.legs is not None:      # a planned gait's leg targets (leg_targets -> SetLegs)
            l1, l2 = cmd.legs
            r.set_legs((l1, l1, l2, l2))
        r.set_winch(cmd.winch)
        self.winch_cmd = cmd.winch
        self.h, self.phi, self.h_band = cmd.height, cmd.phi, cmd.height_band

    def advance(self, dt: float) -> Observation:
        r = self.robot
        x0 = r.x_p
        r.step(dt)
        if r.slipping:
            self.slip += abs(r.x_p - x0)
            if r.winch.command > 0.0:
                self.tug_slip += abs(r.x_p - x0)   # the anchor giving way under a tug
        self.t += dt
        self.energy += r.power * dt
        if self.heavier_at is not None and r.winch.spool_position >= self.heavier_at:
            r.winch.sled_mass, self.heavier_at = self.heavier_mass, None
        a = r.leg_angles()
        h = self.h if self.estimate_height is None else self.estimate_height(self)
        state = AnchorState(h, r.theta_b, 0.5 * (a[0] + a[1]), 0.5 * (a[2] + a[3]))
        res = self.predictor.predict(state, self.phi, 'backward')
        cap = res.capacity_N if res.status.has_value and res.capacity_N is not None \
            else float('nan')
        # capacity_node's lower bound for the assumed height: the smallest capacity over the
        # band behavior_node sends with it (range_bound.py), NaN without a value.
        lower = range_minimum(lambda st, ph: self.predictor.predict(st, ph, 'backward'),
                              state, self.phi, {'height': self.h_band}, (0.0, 1.0), math.pi) \
            if math.isfinite(cap) and self.h_band > 0.0 else cap
        cap, status, assumed = cap, str(res.status), None
        if self.capacity_fault is not None:
            fault = self.capacity_fault(self)
            if fault is not None:
                cap, status, assumed = fault
                lower = cap       # a fault's value stands for both
        if not self.dead:
            self.t_capacity = self.t
            self.last = (cap, lower, status, assumed, h)
        cap, lower, status, assumed, h_used = self.last
        return Observation(
            t=self.t, legs=(state.theta_l1, state.theta_l2), t_legs=self.t,
            theta_b=r.theta_b, tension=r.winch.tension, t_tension=self.t,
            spool=r.winch.spool_position, spool_velocity=r.winch.spool_velocity,
            energy=self.energy, link_ok=self.link_ok, capacity=cap, capacity_lower=lower,
            capacity_status=status,
            t_capacity=self.t_capacity, assumed_inputs=assumed, capacity_h=h_used,
            slip_twist=(0.0, 0.0, 0.0))


def run_loop(machine, plant, t_max=120.0, dt=0.01, on_step=None):
    """Step the machine every ``dt`` (s) and the plant in 2 ms steps until done or t_max."""
    obs = Observation(t=0.0)
    while plant.t < t_max and not machine.done:
        plant.apply(machine.step(obs))
        for _ in range(int(round(dt / 0.002))):
            obs = plant.advance(0.002)
        if on_step:
            on_step(plant, machine)
    return machine


def table_ii_machine(predictor, **kw) -> BehaviorMachine:
    """A machine on ``fast_config(**kw)`` choosing among the Table II modes of ``predictor``."""
    cfg = fast_config(**kw)
    return BehaviorMachine(cfg, ModeChooser(predictor, cfg.safety_factor, cfg.phis_rad))


def fast_config(**kw) -> BehaviorConfig:
    base = dict(cycles=2, walk_time_s=1.5, idle_measure_time_s=0.3)
    base.update(kw)
    return BehaviorConfig(**base)
