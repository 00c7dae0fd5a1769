"""Standing and walking: the idle power measured once at start (IDLE_MEASURE), then the walk of
each cycle with the tether paid out so the robot does not drag the sled (WALK; walking also
unburrows the last anchor), and the step off the dug sand before a re-burrow (STEP_OFF).

Why a re-burrow steps off first: every burrow the stack predicts (the planner's gait map, the
replay of the measured legs, Table II's trials) starts standing on level sand no leg has dug.
A re-burrow in place starts from where the failed anchor left the body, its legs swung back to
standing through their own holes: another start, another burrow. On the simulator's physics
body (600 g sled, the stream of leg targets behavior_node sends) g-60/-20>-40/-20 ends at a
pitch of 16.5 deg from a fresh start, as its plan predicts, but at 24.2 deg as the third burrow
in one place, where the anchor holds nothing; after any walk (0.5-2 s) it ends at 16.6 deg
(docs/design/burrow-planner.md, "Re-burrow on fresh sand"). The legs dig within half a C-leg
(45 mm) of each axle and the axles are 90 mm apart, so the robot stands clear of its holes
after about 0.18 m (step_off_m).

Units: s, J, W, m/s, m. The walk's time so far in a cycle is the cycle tally's walk_s, so a
walk interrupted by a link loss (link_wait.py) goes on for what is left of walk_time_s; a
step off likewise for what is left of step_off_m at walk_speed_m_s. Both count as walking in
the cycle's report (time, energy, distance).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .states import WALKING, State

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
        self.stepped_s = 0.0     # s of the step off under way walked before an interruption
        self.on_enter = {State.IDLE_MEASURE: self._enter_idle_measure,
                         State.WALK: self._enter_walk, State.STEP_OFF: self._enter_step_off}
        self.on_step = {State.IDLE_MEASURE: self._do_idle_measure, State.WALK: self._do_walk,
                        State.STEP_OFF: self._do_step_off}

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
            self._stand()
            m.go(State.CHOOSE, 'walk done')

    def step_off(self, reason: str) -> None:
        """Walk step_off_m (> 0) before the re-burrow burrow.next (module doc)."""
        m = self.m
        self.stepped_s = 0.0
        m.go(State.STEP_OFF, f'{reason}: step {1e3 * m.cfg.step_off_m:.0f} mm off the dug '
                             'sand first')

    def _enter_step_off(self) -> None:
        """Walk, paying out what the robot walks (walk_speed_m_s), not the walk's margin over
        it (payout_speed_m_s): the slacken's slack stays, so the re-burrow's take-up finds the
        rope nearly taut. Paid out at payout_speed_m_s, 0.18 m leaves 60 mm more slack than
        the take-up reels in within take_up_max_s, and the re-burrow would run on a slack
        rope, which the plans do not simulate. A robot faster than walk_speed_m_s takes up
        the slack and then drags the sled, unanchored."""
        self._enter_walk()
        self.m.winch = -self.m.cfg.walk_speed_m_s

    def _do_step_off(self) -> None:
        m = self.m
        if self.stepped_s + m.elapsed() >= m.cfg.step_off_m / m.cfg.walk_speed_m_s:
            self._stand()
            m.burrow.start_next()

    def _stand(self) -> None:
        """End a walk or a step off: stand, winch braked, booked. On a command, not on the
        walk's deadline running out at the bridge (GaitCommand.valid_until, which warns: a
        silent commander)."""
        self.m.command('gait', 'stand')
        self.m.winch = 0.0
        self.pause()

    def pause(self) -> None:
        """Book the walk so far (energy, time) to the cycle: the walk or the step off ends or
        is interrupted."""
        m = self.m
        assert m.state in WALKING
        if m.state == State.STEP_OFF:
            self.stepped_s += m.elapsed()
        m.cycle.walk_j += m.energy_since_enter()
        m.cycle.walk_s += m.elapsed()
