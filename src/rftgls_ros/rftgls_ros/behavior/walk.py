"""Standing and walking: the idle power measured once at start (IDLE_MEASURE), then the walk of
each cycle with the tether paid out so the robot does not drag the sled (WALK; walking also
unburrows the last anchor).

Units: s, J, W, m/s. The walk's time so far in a cycle is the cycle tally's walk_s, so a walk
interrupted by a link loss (link_wait.py) goes on for what is left of walk_time_s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .states import State

if TYPE_CHECKING:
    from .machine import BehaviorMachine


@dataclass(frozen=True)
class EnergyReading:
    """The energy counter (J since bridge start) at time t (s)."""

    t: float
    energy_j: float


class Walk:
    """IDLE_MEASURE and WALK."""

    def __init__(self, machine: BehaviorMachine):
        self.m = machine
        self.idle_from: EnergyReading | None = None   # start of the idle power measurement
        self.on_enter = {State.IDLE_MEASURE: self._enter_idle_measure,
                         State.WALK: self._enter_walk}
        self.on_step = {State.IDLE_MEASURE: self._do_idle_measure, State.WALK: self._do_walk}

    def _enter_idle_measure(self) -> None:
        self.idle_from = None
        self.m.command('gait', 'stand')
        self.m.winch = 0.0

    def _do_idle_measure(self) -> None:
        m, cfg, o = self.m, self.m.cfg, self.m.obs
        if self.idle_from is None and m.elapsed() >= cfg.idle_settle_time_s:
            self.idle_from = EnergyReading(o.t, o.energy)
        if self.idle_from and o.t - self.idle_from.t >= cfg.idle_measure_time_s:
            dt = o.t - self.idle_from.t
            m.idle_power = max(0.0, (o.energy - self.idle_from.energy_j) / dt)
            m.event('info', f'idle power {m.idle_power:.2f} W (removed from burrow '
                            f'energies, as in the paper)')
            m.new_cycle()
            m.go(State.WALK, f'cycle 1/{cfg.cycles}: walk {cfg.walk_time_s:.1f} s')

    def _enter_walk(self) -> None:
        self.m.command('gait', 'walk')
        self.m.winch = -self.m.cfg.payout_speed_m_s
        self.m.mode = None

    def _do_walk(self) -> None:
        m = self.m
        if m.cycle.walk_s + m.elapsed() >= m.cfg.walk_time_s:
            # The walk ends on a command, not on its deadline running out at the bridge
            # (GaitCommand.valid_until, which warns: a silent commander).
            m.command('gait', 'stand')
            m.winch = 0.0
            self.pause()
            m.go(State.CHOOSE, 'walk done')

    def pause(self) -> None:
        """Book the walk so far (energy, time) to the cycle: the walk ends or is interrupted."""
        m = self.m
        m.cycle.walk_j += m.energy_since_enter()
        m.cycle.walk_s += m.elapsed()
