"""The behaviour's parameters (SI), checked once before a run (behavior_node declares one ROS
parameter per field)."""
from __future__ import annotations

import math
from dataclasses import dataclass

# Where the burrows the chooser picks from come from: 'table_ii' the paper's three modes (DH, DL,
# SH) at their Table II poses; 'planned' the burrow planner's gaits (the shipped gait map of the
# configured sled, planned.py). Either way the choice is made on the lower bound.
BURROW_MODES = ('table_ii', 'planned')

@dataclass
class BehaviorConfig:
    """Parameters (SI). Times in s, speeds in m/s (winch reel-in positive), angles in rad.

    cycles: walk-burrow-tug cycles; walk_time_s: walking per cycle (the paper: 8 s);
    walk_speed_m_s: body speed while walking, used only to estimate the distance travelled
    (no odometry on the robot); payout_speed_m_s: tether paid out while walking so the robot does
    not drag the sled; burrow_timeout_s: give up waiting for the final pose (the paper's 8 s);
    burrow_tolerance_rad: leg angle error that counts as "at the final pose"; burrow_settle_s: time
    held at the final pose before the check; replay_timeout_s: time CHECK waits for the
    burrow simulation over the measured leg angles of a planned burrow (replay.py) before the
    plan's predicted pose stands; pitch_check_tolerance_rad: how far the measured pitch may
    lie outside the replayed pitch's band before the burrow counts as not modelled (the IMU's
    static pitch accuracy, about 1 deg for a MEMS IMU: assumed, the paper names no IMU);
    tug_speed_m_s: reel-in speed; arrive_length_m: the tug
    ends when this much tether remains (sled close behind the robot); slow_ratio / stop_ratio:
    tension/capacity at which the tug slows down / stops (margin guard); min_speed_fraction:
    slowest reel speed inside the slow band, as a fraction of tug_speed_m_s; input_timeout_s:
    joint_states/tension age that counts as lost; link_settle_s: time the link must be back
    before resuming; link_wait_s: time to wait for it, then the cycle is recorded aborted
    (link_stale) and the run ends, winch braked; reburrow: on a guard stop or a slip,
    re-burrow into a stronger mode if one suffices (first paying out at slacken_speed_m_s for
    at least slacken_time_s and until the tension is below taut_tension_N, at most
    slacken_max_s), then walking step_off_m (at walk_speed_m_s) off the sand the last burrow
    dug, so the re-burrow starts standing on level sand as every predicted burrow does (0:
    re-burrow in place; walk.py says why); take_up_speed_m_s, take_up_max_s: before every
    burrow the winch reels in the slack at this speed until the tension reaches
    taut_tension_N, for at most this long (0: no take-up): the burrow plans simulate a rope
    just taut when the burrow starts, and a slack one lets the retracting stroke roll the
    robot forward unheld
    (docs/design/burrow-planner.md, "The rope at the burrow's start"); tug_energy_window_s:
    the paper counts only the last 8 s of each tug.

    Evidence (docs/design/tug-safety.md): estimate_timeout_s: age (of its sample) after which
    capacity_node's estimate is not evidence; the winch stops in the step that sees it, so
    the reel after the last estimate is at most (timeout + one expiry check + the stop
    command's way) x tug_speed_m_s; the 0.1 s split: docs/design/stop-budget.md.
    evidence_grace_s: after a *transient* loss (no estimate, too old, 'stale') the winch stays
    stopped and the attempt is aborted if evidence is not back within this time; explicit
    no-value statuses abort at once. capacity_wait_s: time CHECK waits for a usable estimate
    before the tug starts, counted from when the height it checks is settled (the replay of
    a planned burrow done: that height is new to capacity_node). Retry policy: after an abort
    the machine waits, winch braked, for evidence usable for evidence_settle_s, then
    re-checks the same anchor and tugs again as the next cycle; it gives up (FINISHED) if
    evidence is not back within evidence_wait_s or after max_aborts aborts in one run.
    accept_assumed_inputs: inputs capacity_node may assume (status 'assumed') and still
    count as evidence, e.g. ('height',); default none. own_capacity_fallback: when (and only
    when) capacity_node has gone silent after a value-carrying status, use this node's map
    prediction at the Table II height; off by default, never over an explicit no-value status.

    burrow_modes: where the candidate burrows come from (BURROW_MODES): 'table_ii' (the paper's
    DH, DL, SH at their Table II poses) or 'planned' (the burrow planner's gaits from the
    gait map of the configured sled; planned.py). The choice is always the cheapest burrow
    whose lower bound covers safety_factor x need / stop_ratio (ModeChooser says why);
    plan_confidence: the one-sided confidence of a planned gait's lower bound.

    Slip (slip.py): slip_detect on/off, slip_pitch_rad, slip_leg_rad (change under load),
    slip_tension_drop (fraction below the tug's peak while reeling at least slip_min_reel_m).
    """

    cycles: int = 3
    burrow_modes: str = 'planned'
    plan_confidence: float = 0.95
    sled_mass_kg: float = 0.4
    sled_mu: float = 0.5
    safety_factor: float = 1.0
    phis_rad: tuple[float, ...] = (0.0, math.radians(-20.0))
    walk_time_s: float = 2.5
    walk_speed_m_s: float = 0.03
    payout_speed_m_s: float = 0.04
    idle_measure_time_s: float = 1.0
    idle_settle_time_s: float = 0.5
    burrow_timeout_s: float = 8.0
    burrow_tolerance_rad: float = math.radians(3.0)
    burrow_settle_s: float = 0.3
    replay_timeout_s: float = 20.0
    pitch_check_tolerance_rad: float = math.radians(1.0)
    tug_speed_m_s: float = 0.05
    tug_timeout_s: float = 40.0
    arrive_length_m: float = 0.15
    slow_ratio: float = 0.90
    stop_ratio: float = 0.97
    min_speed_fraction: float = 0.1
    taut_tension_N: float = 0.3
    estimate_timeout_s: float = 0.06
    evidence_grace_s: float = 2.0
    evidence_settle_s: float = 0.3
    evidence_wait_s: float = 10.0
    max_aborts: int = 2
    accept_assumed_inputs: tuple[str, ...] = ()
    capacity_wait_s: float = 3.0
    input_timeout_s: float = 0.6
    link_settle_s: float = 0.5
    link_wait_s: float = 60.0
    reburrow: bool = True
    max_burrows_per_cycle: int = 3
    slacken_speed_m_s: float = 0.03
    slacken_time_s: float = 0.3
    slacken_max_s: float = 2.0
    step_off_m: float = 0.18
    take_up_speed_m_s: float = 0.02
    take_up_max_s: float = 3.0
    rope_length_m: float = 0.50
    attach_height_m: float = 0.01
    h_walk_m: float = 0.060
    tug_energy_window_s: float = 8.0
    live_period_s: float = 1.0
    need_alpha: float = 0.5
    energy_prior_sh_J: float = 1.0
    pose_snap_rad: float = math.radians(0.5)
    own_capacity_fallback: bool = False
    slip_detect: bool = True
    slip_pitch_rad: float = math.radians(1.0)
    slip_leg_rad: float = math.radians(2.0)
    slip_tension_drop: float = 0.15
    slip_min_reel_m: float = 0.003

    def check(self) -> BehaviorConfig:
        """ValueError (one line) on values the machine cannot run with; returns self."""
        if self.burrow_modes not in BURROW_MODES:
            raise ValueError(f'burrow_modes must be one of {", ".join(BURROW_MODES)}, got '
                             f'{self.burrow_modes!r}')
        if not 0.5 <= self.plan_confidence < 1.0:
            raise ValueError(f'plan_confidence must be in [0.5, 1), got {self.plan_confidence}')
        if self.cycles < 1 or self.max_aborts < 0 or self.max_burrows_per_cycle < 1:
            raise ValueError('cycles and max_burrows_per_cycle must be >= 1, max_aborts >= 0')
        if not 0.0 < self.slow_ratio <= self.stop_ratio:
            raise ValueError(f'need 0 < slow_ratio <= stop_ratio, got {self.slow_ratio} and '
                             f'{self.stop_ratio}')
        if not self.phis_rad or any(abs(p) > math.pi / 2 for p in self.phis_rad):
            raise ValueError(f'phis_rad must be tether angles within +-pi/2, '
                             f'got {list(self.phis_rad)}')
        if not (self.pitch_check_tolerance_rad >= 0.0
                and math.isfinite(self.pitch_check_tolerance_rad)):
            raise ValueError(f'pitch_check_tolerance_rad must be >= 0, got '
                             f'{self.pitch_check_tolerance_rad}')
        for name in ('take_up_max_s', 'step_off_m'):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ValueError(f'{name} must be >= 0, got {getattr(self, name)!r}')
        for name in ('replay_timeout_s', 'walk_time_s', 'burrow_timeout_s', 'tug_timeout_s',
                     'tug_speed_m_s', 'input_timeout_s', 'estimate_timeout_s', 'sled_mass_kg',
                     'take_up_speed_m_s', 'walk_speed_m_s'):
            if not getattr(self, name) > 0:
                raise ValueError(f'{name} must be > 0, got {getattr(self, name)!r}')
        return self
