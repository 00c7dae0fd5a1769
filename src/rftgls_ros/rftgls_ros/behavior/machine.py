"""The walk-burrow-tug state machine (paper section VI-C), without ROS.

    WAIT_INPUTS -> IDLE_MEASURE -> [ WALK -> CHOOSE -> BURROW -> CHECK -> TUG -> CYCLE_DONE ] x N
                                                 |          ^        |     |
                                                 v          +-SLACKEN<-HOLD (margin guard,
                                              REFUSED                     |  slip, short)
                                                                     FINISHED (no stronger mode)
    CHECK, TUG --evidence lost--> WAIT_EVIDENCE --evidence back--> CHECK (next cycle)
                                       +--no evidence in time / too many aborts--> FINISHED
    any active state --link lost / inputs stale--> WAIT_LINK --back--> resume

A tug runs only on live evidence (``evidence.judge``; docs/design/tug-safety.md): without a
fresh, value-carrying, accepted estimate from capacity_node the winch is stopped in the same
step, and the attempt is recorded ``aborted`` with the reason code.

``step(obs)`` takes an ``Observation`` (SI values and their times, s) and returns the
``Commands`` to publish, with the step's events (dicts with a human ``text``: every
transition and decision), which the node logs and publishes. ``events`` keeps the recent
history for inspection. The states are a table: ``_handlers`` (state -> step handler) and
``_on_enter`` (state -> entry action); why a tug stopped is a ``HoldCause``.
"""
from __future__ import annotations

import enum
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from rftgls_core.types import AnchorState, Status

from . import evidence
from .model import ANCHOR_MODES, Decision, EnergyModel, ForceNeed, ModeChooser, TetherTracker
from .report import CycleRecord
from .slip import SlipDetector, SlipEvent


class State(str, enum.Enum):
    WAIT_INPUTS = 'WAIT_INPUTS'
    IDLE_MEASURE = 'IDLE_MEASURE'
    WALK = 'WALK'
    CHOOSE = 'CHOOSE'
    BURROW = 'BURROW'
    CHECK = 'CHECK'
    TUG = 'TUG'
    HOLD = 'HOLD'
    SLACKEN = 'SLACKEN'
    CYCLE_DONE = 'CYCLE_DONE'
    WAIT_LINK = 'WAIT_LINK'
    WAIT_EVIDENCE = 'WAIT_EVIDENCE'
    REFUSED = 'REFUSED'
    FINISHED = 'FINISHED'

    def __str__(self) -> str:
        return self.value


class HoldCause(enum.Enum):
    """Why the winch was stopped in a cycle (the HOLD state's cause and the cycle's outcome).
    The cycle CSV keeps its reason codes: margin_guard, capacity_short, slip_* (slip.py) and
    the evidence codes of an aborted attempt (evidence.py)."""

    NONE = 'none'
    GUARD = 'guard'          # margin guard: tension reached stop_ratio x capacity
    SHORT = 'short'          # capacity below the required force
    SLIP = 'slip'            # the anchor moved under load
    EVIDENCE = 'evidence'    # no usable capacity estimate (aborted attempt)


# What a HOLD re-burrow is called in the transition text.
REBURROW_WHY = {HoldCause.GUARD: 'margin guard stop', HoldCause.SLIP: 'anchor slip',
                HoldCause.SHORT: 'capacity below need'}
EVENT_HISTORY = 10000   # events kept in BehaviorMachine.events

ACTIVE = {State.IDLE_MEASURE, State.WALK, State.CHOOSE, State.BURROW, State.CHECK, State.TUG,
          State.HOLD, State.SLACKEN, State.CYCLE_DONE, State.WAIT_EVIDENCE}
TERMINAL = {State.REFUSED, State.FINISHED}


@dataclass
class BehaviorConfig:
    """Parameters (SI). Times in s, speeds in m/s (winch reel-in positive), angles in rad.

    cycles: walk-burrow-tug cycles; walk_time_s: walking per cycle (the paper: 8 s);
    walk_speed_m_s: body speed while walking, used only to estimate the distance travelled
    (no odometry on the robot); payout_speed_m_s: tether paid out while walking so the robot does
    not drag the sled; burrow_timeout_s: give up waiting for the final pose (the paper's 8 s);
    burrow_tolerance_rad: leg angle error that counts as "at the final pose"; burrow_settle_s: time
    held at the final pose before the check; tug_speed_m_s: reel-in speed; arrive_length_m: the tug
    ends when this much tether remains (sled close behind the robot); slow_ratio / stop_ratio:
    tension/capacity at which the tug slows down / stops (margin guard); min_speed_fraction:
    slowest reel speed inside the slow band, as a fraction of tug_speed_m_s; input_timeout_s:
    joint_states/tension age that counts as lost; link_settle_s: time the link must be back
    before resuming; reburrow: on a guard stop or a slip, re-burrow into a stronger mode if
    one suffices; tug_energy_window_s: the paper counts only the last 8 s of each tug.

    Evidence (docs/design/tug-safety.md): estimate_timeout_s: age (receipt time) after which
    capacity_node's estimate is not evidence; the winch stops in the step that sees it, so
    the reel after the last estimate is at most (timeout + one step) x tug_speed_m_s.
    evidence_grace_s: after a *transient* loss (no estimate, too old, 'stale') the winch stays
    stopped and the attempt is aborted if evidence is not back within this time; explicit
    no-value statuses abort at once. capacity_wait_s: time CHECK waits for a usable estimate
    before the tug starts (the pose has just settled). Retry policy: after an abort the
    machine waits, winch braked, for evidence usable for evidence_settle_s, then re-checks the
    same anchor and tugs again as the next cycle; it gives up (FINISHED) if evidence is not
    back within evidence_wait_s or after max_aborts aborts in one run.
    accept_assumed_inputs: inputs capacity_node may assume (status 'assumed') and still
    count as evidence, e.g. ('height',); default none. own_capacity_fallback: when (and only
    when) capacity_node has gone silent after a value-carrying status, use this node's map
    prediction at the Table II height; off by default, never over an explicit no-value status.

    Slip (slip.py): slip_detect on/off, slip_pitch_rad, slip_leg_rad (change under load),
    slip_tension_drop (fraction below the tug's peak while reeling at least slip_min_reel_m).
    """

    cycles: int = 3
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
    tug_speed_m_s: float = 0.05
    tug_timeout_s: float = 40.0
    arrive_length_m: float = 0.15
    slow_ratio: float = 0.90
    stop_ratio: float = 0.97
    min_speed_fraction: float = 0.1
    taut_tension_N: float = 0.3
    estimate_timeout_s: float = 0.05
    evidence_grace_s: float = 2.0
    evidence_settle_s: float = 0.3
    evidence_wait_s: float = 10.0
    max_aborts: int = 2
    accept_assumed_inputs: tuple[str, ...] = ()
    capacity_wait_s: float = 1.0
    input_timeout_s: float = 0.6
    link_settle_s: float = 0.5
    reburrow: bool = True
    max_burrows_per_cycle: int = 3
    slacken_speed_m_s: float = 0.03
    slacken_time_s: float = 0.3
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
        if self.cycles < 1 or self.max_aborts < 0 or self.max_burrows_per_cycle < 1:
            raise ValueError('cycles and max_burrows_per_cycle must be >= 1, max_aborts >= 0')
        if not 0.0 < self.slow_ratio <= self.stop_ratio:
            raise ValueError(f'need 0 < slow_ratio <= stop_ratio, got {self.slow_ratio} and '
                             f'{self.stop_ratio}')
        if not self.phis_rad or any(abs(p) > math.pi / 2 for p in self.phis_rad):
            raise ValueError(f'phis_rad must be tether angles within +-pi/2, '
                             f'got {list(self.phis_rad)}')
        for name in ('walk_time_s', 'burrow_timeout_s', 'tug_timeout_s', 'tug_speed_m_s',
                     'input_timeout_s', 'estimate_timeout_s', 'sled_mass_kg'):
            if not getattr(self, name) > 0:
                raise ValueError(f'{name} must be > 0, got {getattr(self, name)!r}')
        return self


@dataclass
class Observation:
    """What the robot and capacity_node last said, with receive times t_* (s, node clock).

    legs: (thetaL1, thetaL2) rad (left/right averaged); theta_b rad; tension N; spool m
    reeled since MCU boot and spool_velocity m/s (reel-in positive); energy J since bridge
    start; power W; link_ok from /minirquad/link_state; capacity N along the tether and its
    status word from capacity_node; assumed_inputs the input names capacity_node reported
    as assumed (None = not received); slip_twist (vx, vz, wy) unit direction in the anchor
    frame.
    """

    t: float
    legs: tuple[float, float] | None = None
    t_legs: float = -math.inf
    theta_b: float | None = None
    tension: float | None = None
    t_tension: float = -math.inf
    spool: float | None = None
    spool_velocity: float = 0.0
    energy: float | None = None
    power: float | None = None
    link_ok: bool = False
    capacity: float | None = None
    capacity_status: str = 'stale'
    t_capacity: float = -math.inf
    assumed_inputs: frozenset[str] | None = None
    slip_twist: tuple[float, float, float] | None = None


@dataclass
class Commands:
    """To publish after a step: one-shot ``gait``/``burrow`` commands (in order), the winch
    reel-in set-point (m/s, 0 brakes), h (m) and phi (rad) for capacity_node, and the events
    of this step (to log and publish, in order). h is assumed, never measured (MiniRQuad has
    no sensor for it): height_band is the half-width of its range (m, NaN = not stated) and
    height_source says where the number comes from."""

    oneshots: list[tuple[str, str]]
    winch: float
    height: float
    phi: float
    events: list[dict] = field(default_factory=list)
    height_band: float = math.nan
    height_source: str = ''


@dataclass
class _Cycle:
    index: int
    modes: list[str] = field(default_factory=list)
    walk_j: float = 0.0
    walk_s: float = 0.0
    burrow_j: float = 0.0
    burrow_s: float = 0.0
    tug_j: float = 0.0
    tug_total_j: float = 0.0
    tug_s: float = 0.0
    sled_distance: float = 0.0
    outcome: str = ''
    reason: str = ''          # the CSV reason code
    cause: HoldCause = HoldCause.NONE
    need_n: float = 0.0
    min_margin: float = math.inf
    tensions: list[float] = field(default_factory=list)


class BehaviorMachine:
    """The behaviour. ``chooser`` answers capacity predictions (map), the rest is owned here."""

    def __init__(self, config: BehaviorConfig, chooser: ModeChooser):
        self.cfg = config
        self.chooser = chooser
        self.need = ForceNeed(config.sled_mass_kg, config.sled_mu, alpha=config.need_alpha)
        self.energy = EnergyModel(prior_sh=config.energy_prior_sh_J)
        self.tether = TetherTracker(config.rope_length_m, config.attach_height_m)
        self.state = State.WAIT_INPUTS
        self.events: deque[dict] = deque(maxlen=EVENT_HISTORY)
        self._step_events: list[dict] = []
        self.records: list[CycleRecord] = []
        self.decisions: list[Decision] = []
        self.cycle: _Cycle | None = None
        self.mode: str | None = None
        self.reason = 'waiting for the robot and capacity_node'
        self._oneshots: list[tuple[str, str]] = []
        self._winch = 0.0
        self._t_enter = 0.0
        self._e_enter: float | None = None
        self._resume: State | None = None
        self._link_back_at: float | None = None
        self._idle_power = 0.0
        self._tug_hist: deque[tuple[float, float]] = deque()
        self._last_live = -math.inf
        self._weakest: float | None = None
        self._burrows = 0
        self._at_pose_since: float | None = None
        self._last_spool: float | None = None
        self._walk_elapsed = 0.0
        self.obs = Observation(t=0.0)
        self.capacity_source = ''
        self._fallback_warned = False
        self.aborts = 0
        self.slip = SlipDetector(config.slip_pitch_rad, config.slip_leg_rad,
                                 config.slip_tension_drop, config.slip_min_reel_m,
                                 config.taut_tension_N)
        self._hold_cause = HoldCause.NONE
        # Per-state scratch, (re)set by the entry actions.
        self._idle_e0: tuple[float, float] | None = None
        self._checked = False
        self._check_why = ''
        self._check_unanswered = False   # the pose check's questions went unanswered
        self._next_mode: str | None = None
        self._next_reason = ''
        self._tug_tensions: list[float] = []
        self._tug_start_t = 0.0
        self._usable_since: float | None = None
        self._gap: tuple[float, float | None] | None = None
        self._good: tuple[float, float | None] | None = None
        self._stop_watch: tuple[float, float | None, str, str] | None = None
        self._last_value_status = False
        self._handlers: dict[State, Callable[[], None]] = {
            State.WAIT_INPUTS: self._do_wait_inputs, State.IDLE_MEASURE: self._do_idle_measure,
            State.WALK: self._do_walk, State.CHOOSE: self._do_choose,
            State.BURROW: self._do_burrow, State.CHECK: self._do_check, State.TUG: self._do_tug,
            State.HOLD: self._do_hold, State.SLACKEN: self._do_slacken,
            State.CYCLE_DONE: self._do_cycle_done, State.WAIT_LINK: self._do_wait_link,
            State.WAIT_EVIDENCE: self._do_wait_evidence,
            # REFUSED and FINISHED are terminal: nothing to do.
        }
        self._on_enter: dict[State, Callable[[], None]] = {
            State.IDLE_MEASURE: self._enter_idle_measure, State.WALK: self._enter_walk,
            State.BURROW: self._enter_burrow, State.CHECK: self._enter_check,
            State.TUG: self._enter_tug, State.SLACKEN: self._enter_slacken,
            State.WAIT_EVIDENCE: self._enter_wait_evidence,
        }

    # ------------------------------------------------------------------ helpers
    def _event(self, kind: str, text: str, **extra) -> None:
        ev = {'t': round(self.obs.t, 3), 'kind': kind, 'state': str(self.state), 'text': text,
              **extra}
        self.events.append(ev)
        self._step_events.append(ev)

    def _go(self, new: State, reason: str) -> None:
        old = self.state
        self.state = new
        self.reason = reason
        self._t_enter = self.obs.t
        self._e_enter = self.obs.energy
        self._event('transition', f'{old} -> {new}: {reason}', **{'from': str(old),
                                                                 'to': str(new)})
        enter = self._on_enter.get(new)
        if enter is not None:
            enter()

    def _elapsed(self) -> float:
        return self.obs.t - self._t_enter

    def _energy_since_enter(self) -> float:
        if self.obs.energy is None or self._e_enter is None:
            return 0.0
        return self.obs.energy - self._e_enter

    @property
    def height(self) -> float:
        """Height of p (m): not measured on MiniRQuad; the burrowed mode's Table II mean."""
        return self.height_input()[0]

    def height_input(self) -> tuple[float, float, str]:
        """(h m, band m, source) of the assumed height of p: the burrowed mode's Table II
        mean within H_BAND_SDS of its standard deviations, else h_walk_m (band not stated)."""
        if self.mode and self.state in (State.BURROW, State.CHECK, State.TUG, State.HOLD,
                                        State.SLACKEN, State.CYCLE_DONE, State.REFUSED,
                                        State.FINISHED, State.WAIT_LINK,
                                        State.WAIT_EVIDENCE):
            m = ANCHOR_MODES[self.mode]
            return m.h, m.h_band, f'Table II mean of {m.name} (paper), not measured'
        return self.cfg.h_walk_m, math.nan, 'h_walk_m parameter (walking), not measured'

    def _inputs_fresh(self) -> bool:
        o = self.obs
        return (o.link_ok and o.t - o.t_legs <= self.cfg.input_timeout_s
                and o.t - o.t_tension <= self.cfg.input_timeout_s)

    def evidence(self) -> evidence.Verdict:
        """Is capacity_node's last estimate usable evidence for tugging now?"""
        o = self.obs
        return evidence.judge(o.t, o.capacity, o.capacity_status, o.t_capacity,
                              self.cfg.estimate_timeout_s, o.assumed_inputs,
                              frozenset(self.cfg.accept_assumed_inputs))

    def capacity_valid(self) -> bool:
        return self.evidence().usable

    def measured_state(self) -> AnchorState | None:
        if self.mode is None or self.obs.legs is None:
            return None
        m = ANCHOR_MODES[self.mode]
        tb = self.obs.theta_b if self.obs.theta_b is not None else m.theta_b
        l1, l2 = self.obs.legs
        if abs(l1 - m.final[0]) <= self.cfg.pose_snap_rad:
            l1 = m.final[0]
        if abs(l2 - m.final[1]) <= self.cfg.pose_snap_rad:
            l2 = m.final[1]
        return AnchorState(m.h, tb, l1, l2)

    def own_capacity(self) -> tuple[float | None, str]:
        """This node's map prediction (N, status) at the measured pose and estimated phi."""
        state = self.measured_state()
        if state is None:
            return None, 'stale'
        cap, status = self.chooser.capacity(state, self.tether.phi(self.height))
        return cap, str(status)

    # ------------------------------------------------------------------ step
    def step(self, obs: Observation) -> Commands:
        self.obs = obs
        if obs.spool is not None and obs.spool != self._last_spool:
            if self._last_spool is not None and self.state == State.TUG and self.cycle \
                    and (obs.tension or 0.0) > self.cfg.taut_tension_N:
                d = obs.spool - self._last_spool
                if 0.0 < d < 0.2:
                    self.cycle.sled_distance += d
            self.tether.update(obs.spool)
            self._last_spool = obs.spool
        if self.state in ACTIVE and not self._inputs_fresh():
            if self.state == State.WALK:
                self._walk_elapsed += self._elapsed()
                self.cycle.walk_j += self._energy_since_enter()
                self.cycle.walk_s += self._elapsed()
            self._resume = self.state
            self._winch = 0.0
            if self.state == State.TUG and self._stop_watch is None and self._good:
                self._stop_watch = (*self._good, 'link_stale', 'the last usable estimate')
            what = 'link stale' if not obs.link_ok else 'joint_states/tension stale'
            self._go(State.WAIT_LINK, f'{what} during {self._resume}: winch stopped, waiting')
        handler = self._handlers.get(self.state)
        if handler is not None:
            handler()
        self._watch_stop()
        h, band, source = self.height_input()
        out = Commands(self._oneshots, self._winch, h, self.tether.phi(h), self._step_events,
                       band, source)
        self._oneshots, self._step_events = [], []
        return out

    def _watch_stop(self) -> None:
        """After a safety stop, report once how far the spool went after the last usable
        estimate (m) when the encoder shows it standing still: what the robot measured."""
        w, o = self._stop_watch, self.obs
        if w is None or o.spool is None or abs(o.spool_velocity) > 1e-6:
            return
        t0, spool0, reason, since = w
        self._stop_watch = None
        reel = (o.spool - spool0) if spool0 is not None else float('nan')
        self._event('stop', f'winch standing after {reason}: {1e3 * reel:.1f} mm reeled in '
                            f'since {since} ({1e3 * (o.t - t0):.0f} ms before)',
                    reason=reason, reel_m=reel, since_s=o.t - t0)

    # ------------------------------------------------------------------ states
    def _do_wait_inputs(self) -> None:
        o = self.obs
        if self._inputs_fresh() and o.energy is not None:
            self._go(State.IDLE_MEASURE, 'robot link ok, sensors fresh')

    def _enter_idle_measure(self) -> None:
        self._idle_e0 = None
        self._oneshots.append(('gait', 'stand'))
        self._winch = 0.0

    def _do_idle_measure(self) -> None:
        if self._idle_e0 is None and self._elapsed() >= self.cfg.idle_settle_time_s:
            self._idle_e0 = (self.obs.t, self.obs.energy)
        if self._idle_e0 and self.obs.t - self._idle_e0[0] >= self.cfg.idle_measure_time_s:
            dt = self.obs.t - self._idle_e0[0]
            self._idle_power = max(0.0, (self.obs.energy - self._idle_e0[1]) / dt)
            self._event('info', f'idle power {self._idle_power:.2f} W (removed from burrow '
                                f'energies, as in the paper)')
            self._new_cycle()
            self._go(State.WALK, f'cycle 1/{self.cfg.cycles}: walk {self.cfg.walk_time_s:.1f} s')

    def _new_cycle(self) -> None:
        idx = 1 if self.cycle is None else self.cycle.index + 1
        self.cycle = _Cycle(idx)
        self._burrows = 0
        self._walk_elapsed = 0.0

    def _enter_walk(self) -> None:
        self._oneshots.append(('gait', 'walk'))
        self._winch = -self.cfg.payout_speed_m_s
        self.mode = None

    def _do_walk(self) -> None:
        if self._walk_elapsed + self._elapsed() >= self.cfg.walk_time_s:
            self._winch = 0.0
            self.cycle.walk_j += self._energy_since_enter()
            self.cycle.walk_s += self._elapsed()
            self._go(State.CHOOSE, 'walk done')

    def _do_choose(self) -> None:
        d = self.chooser.choose(self.need.value, self.energy)
        self._decide(d)
        if d.mode is None:
            self._refuse(d.reason)
        else:
            self._burrow(d.mode, d.reason)

    def _decide(self, d: Decision) -> None:
        self.decisions.append(d)
        self._event('decision', f'decision ({d.pose} pose): {d.reason}\n{d.table()}',
                    mode=d.mode, need_n=d.need_n,
                    candidates=[{'mode': c.mode, 'capacities': c.capacities,
                                 'statuses': c.statuses, 'energy_j': c.energy_j,
                                 'sufficient': c.sufficient, 'why': c.why}
                                for c in d.candidates])

    def _refuse(self, reason: str) -> None:
        self._winch = 0.0
        self._oneshots.append(('gait', 'stand'))
        if self.cycle:
            self.cycle.outcome = 'refused'
            self._record()
        self._go(State.REFUSED, f'not tugging: {reason}')

    def _burrow(self, mode: str, reason: str) -> None:
        self.mode = mode
        self._burrows += 1
        self.cycle.modes.append(mode)
        self._go(State.BURROW, f'burrow {mode}: {reason.split(";")[0]}')

    def _enter_burrow(self) -> None:
        self._winch = 0.0
        self._at_pose_since = None
        self._oneshots.append(('burrow', self.mode))

    def _do_burrow(self) -> None:
        m = ANCHOR_MODES[self.mode]
        legs = self.obs.legs
        at = legs is not None and max(abs(legs[0] - m.final[0]),
                                      abs(legs[1] - m.final[1])) <= self.cfg.burrow_tolerance_rad
        if at and self._at_pose_since is None:
            self._at_pose_since = self.obs.t
        elif not at:
            self._at_pose_since = None
        done = at and self.obs.t - self._at_pose_since >= self.cfg.burrow_settle_s
        timeout = self._elapsed() >= self.cfg.burrow_timeout_s
        if done or timeout:
            dt, de = self._elapsed(), self._energy_since_enter()
            self.cycle.burrow_j += de
            self.cycle.burrow_s += dt
            above_idle = de - self._idle_power * dt
            self.energy.update(self.mode, above_idle)
            self._event('info', f'burrow {self.mode}: {de:.2f} J in {dt:.1f} s '
                                f'({above_idle:.2f} J above idle); energy estimates now '
                        + ', '.join(f'{k} {self.energy.estimate(k):.2f} J'
                                    for k in ANCHOR_MODES))
            self._go(State.CHECK, 'at the final pose' if done else
                     f'burrow timeout ({self.cfg.burrow_timeout_s:.0f} s): checking the pose '
                     'reached')

    def _enter_check(self) -> None:
        self._winch = 0.0
        self._checked = False
        self._check_unanswered = False

    def _do_check(self) -> None:
        if not self._checked:
            self._check_prediction()
            return
        # The prediction holds; the tug starts only on capacity_node's live evidence.
        v = self.evidence()
        if not v.usable:
            if self._elapsed() >= self.cfg.capacity_wait_s:
                self._abort(v, in_tug=False)
            return
        cap = self.obs.capacity * self.chooser.scale
        required = self.cfg.safety_factor * self.need.value
        if cap < required:
            self._event('decision', f'capacity_node: {self.mode} holds {cap:.2f} N < '
                                    f'{required:.2f} N required', mode=self.mode)
            self._reselect(f'{self.mode} insufficient per capacity_node', cap)
            return
        self._go(State.TUG, f'{self.mode} holds at the measured pose ({self._check_why}; '
                            f'capacity_node {cap:.2f} N >= {required:.2f} N)')

    def _check_prediction(self) -> None:
        state = self.measured_state()
        if state is None:
            return
        c = self.chooser.evaluate(self.mode, state, self.need.value,
                                  self.energy.estimate(self.mode))
        self._weakest = c.weakest
        if not c.sufficient and all(s == str(Status.STALE) for s in c.statuses):
            self._check_missing_evidence()
            return
        pose = (f'measured pose thetaL1 {math.degrees(state.theta_l1):.1f}, thetaL2 '
                f'{math.degrees(state.theta_l2):.1f}, thetaB {math.degrees(state.theta_b):.1f} '
                f'deg, h {1e3 * state.h:.0f} mm (Table II mean, not measured)')
        caps = '/'.join(f'{x:.2f}' if x is not None else s
                        for x, s in zip(c.capacities, c.statuses))
        self._event('decision', f'check {self.mode} at the {pose}: capacity {caps} N -> '
                                f'{"sufficient" if c.sufficient else "insufficient"} '
                                f'({c.why})', mode=self.mode, capacities=c.capacities)
        if c.sufficient:
            self._checked, self._check_why = True, c.why
            self._do_check()
            return
        self._reselect(f'{self.mode} insufficient at the measured pose', c.weakest)

    def _check_missing_evidence(self) -> None:
        """The pose check's questions came back `stale` (capacity_node's query service
        unanswered): evidence is missing, the anchor is not shown insufficient. The evidence
        rule decides, as in the live check: wait, then abort and retry by the policy."""
        if not self._check_unanswered:
            self._check_unanswered = True
            self._event('warn', f'check {self.mode}: the capacity query is unanswered (stale); '
                                'waiting for evidence, not re-burrowing', mode=self.mode)
        if self._elapsed() >= self.cfg.capacity_wait_s:
            v = self.evidence()
            self._abort(v if not v.usable else evidence.Verdict(
                False, evidence.NO_VALUE, True, 'capacity query unanswered'), in_tug=False)

    def _reselect(self, why: str, weakest: float | None) -> None:
        if self._burrows >= self.cfg.max_burrows_per_cycle:
            self._stop_cycle(f'{why}; {self._burrows} burrows this cycle, giving up')
            return
        d = self.chooser.choose(self.need.value, self.energy, exclude=[self.mode],
                                stronger_than=weakest, pose='expected')
        self._decide(d)
        if d.mode is None:
            self._stop_cycle(f'{why}; {d.reason}')
        else:
            self._next_mode = d.mode
            self._next_reason = f'{why}; re-burrow: {d.reason}'
            self._go(State.SLACKEN, f'{why}: slacken the tether, then re-burrow {d.mode}')

    def _stop_cycle(self, reason: str) -> None:
        self._winch = 0.0
        self.cycle.outcome = 'stopped'
        self._record()
        what = 'stopped after a slip' if self.cycle.cause is HoldCause.SLIP \
            else 'stopped before slip'
        self._go(State.FINISHED, f'{what}, winch braked: {reason}')

    def _enter_slacken(self) -> None:
        self._winch = -self.cfg.slacken_speed_m_s

    def _do_slacken(self) -> None:
        if self._elapsed() >= self.cfg.slacken_time_s:
            self._winch = 0.0
            self._burrow(self._next_mode, self._next_reason)

    def _enter_tug(self) -> None:
        self._tug_hist.clear()
        self._gap = None
        self._good = (self.obs.t, self.obs.spool)
        self._last_live = -math.inf
        self._tug_tensions = []
        self._tug_start_t = self.obs.t
        self._fallback_warned = False
        self.slip.reset()

    def _do_tug(self) -> None:
        """One tug step: end or slip first, then evidence, then the margin guard, then reel."""
        if self.obs.energy is not None:
            self._tug_hist.append((self.obs.t, self.obs.energy))
        if self._tug_ended() or self._tug_slipped():
            return
        got = self._tug_evidence()
        if got is None:
            return
        capacity, source = got
        if self._tug_short(capacity, source) or self._tug_guard(capacity, source):
            return
        self._tug_reel(capacity, source)

    def _tug_ended(self) -> bool:
        """The sled arrived or the tug timed out (winch stopped, state changed)."""
        cfg = self.cfg
        if self.tether.free_length <= cfg.arrive_length_m:
            self._winch = 0.0
            self._finish_tug('arrived')
            self._go(State.CYCLE_DONE, f'sled arrived ({self.tether.free_length:.3f} m of '
                                       'tether left)')
            return True
        if self._elapsed() > cfg.tug_timeout_s:
            self._winch = 0.0
            self._finish_tug('timeout')
            self._stop_cycle(f'tug timeout ({cfg.tug_timeout_s:.0f} s)')
            return True
        return False

    def _tug_slipped(self) -> bool:
        """The slip detector fired (see _on_slip)."""
        o = self.obs
        if not self.cfg.slip_detect:
            return False
        ev = self.slip.update(o.tension, o.spool, o.theta_b, o.legs)
        if ev is None:
            return False
        self._on_slip(ev)
        return True

    def _tug_evidence(self) -> tuple[float, str] | None:
        """(capacity N scaled by the chooser's slip correction, its source), or None when
        there is no usable evidence (the winch is stopped by _evidence_gap)."""
        cfg, o = self.cfg, self.obs
        v = self.evidence()
        capacity, source = o.capacity, 'capacity_node'
        if not v.usable and cfg.own_capacity_fallback and self._last_value_status \
                and v.reason in (evidence.NO_ESTIMATE, evidence.TIMEOUT):
            # capacity_node went silent after a value: only then, and only when configured.
            cap, status = self.own_capacity()
            if cap is not None and status == 'ok':
                if not self._fallback_warned:
                    self._fallback_warned = True
                    self._event('warn', f'capacity_node silent ({v.detail}): using '
                                        f'behavior_node\'s own map prediction at the measured '
                                        f'pose and the Table II height (own_capacity_fallback)')
                capacity, source = cap, 'own map'
                v = evidence.Verdict(True, evidence.USABLE, False, 'own map')
        if not v.usable:
            self._evidence_gap(v)
            return None
        assert capacity is not None  # usable evidence carries a value (evidence.judge)
        if source == 'capacity_node':
            self._last_value_status = True
        if self._gap is not None:
            # Evidence back before the encoder showed the spool standing: nothing to report.
            self._stop_watch = None
        self._gap = None
        self._good = (o.t, o.spool)
        return capacity * self.chooser.scale, source

    def _tug_short(self, capacity: float, source: str) -> bool:
        """Capacity below the required force: stop and hold (SHORT)."""
        required = self.cfg.safety_factor * self.need.value
        if capacity >= required:
            return False
        self._winch = 0.0
        self._finish_tug('short')
        self._hold(HoldCause.SHORT, f'capacity {capacity:.2f} N ({source}) below the required '
                                    f'{required:.2f} N: winch stopped', 'capacity_short')
        return True

    def _tug_guard(self, capacity: float, source: str) -> bool:
        """Margin guard: tension at stop_ratio x capacity stops the winch before the slip."""
        cfg = self.cfg
        self.capacity_source = source
        tension = self.obs.tension or 0.0
        ratio = tension / capacity if capacity > 0 else math.inf
        self.cycle.min_margin = min(self.cycle.min_margin, capacity - tension)
        if ratio < cfg.stop_ratio:
            return False
        self._winch = 0.0
        self._finish_tug('guard stop')
        self.need.raise_floor(tension)
        twist = self._twist_text()
        self._hold(HoldCause.GUARD, f'margin guard: tension {tension:.2f} N >= '
                                    f'{cfg.stop_ratio:.2f} x capacity {capacity:.2f} N '
                                    f'({source}), winch stopped before the predicted slip '
                                    f'{twist}', 'margin_guard')
        return True

    def _tug_reel(self, capacity: float, source: str) -> None:
        """Reel in, slower inside the slow band; sample the sliding tension; a live event
        every live_period."""
        cfg, o = self.cfg, self.obs
        tension = o.tension or 0.0
        ratio = tension / capacity if capacity > 0 else math.inf
        band = max(cfg.stop_ratio - cfg.slow_ratio, 1e-6)
        frac = min(1.0, max(cfg.min_speed_fraction, (cfg.stop_ratio - ratio) / band))
        self._winch = cfg.tug_speed_m_s * frac
        if tension > cfg.taut_tension_N and o.spool_velocity > 0.5 * self._winch > 0:
            self._tug_tensions.append(tension)
        if o.t - self._last_live >= cfg.live_period_s:
            self._last_live = o.t
            self._event('live', f'tug {self.mode}: T {tension:.2f} N, C {capacity:.2f} N '
                                f'({source}), margin {capacity - tension:+.2f} N '
                                f'({100 * (1 - ratio):.0f}'
                                f' %), phi {math.degrees(self.tether.phi(self.height)):.0f} deg,'
                                f' slip twist {self._twist_text()}, status '
                                f'{o.capacity_status}, reel {1e3 * self._winch:.0f} mm/s, '
                                f'tether {self.tether.free_length:.3f} m',
                        tension=tension, capacity=capacity, source=source)

    def _hold(self, cause: HoldCause, text: str, reason: str) -> None:
        """Winch stopped for `cause`; `reason` is the cycle's CSV reason code."""
        self._hold_cause = cause
        self.cycle.cause, self.cycle.reason = cause, reason
        self._go(State.HOLD, text)

    def _evidence_gap(self, v: evidence.Verdict) -> None:
        """No usable evidence in TUG: winch stopped now; abort now or after the grace time."""
        o = self.obs
        self._winch = 0.0
        if self._gap is None:
            self._gap = (o.t, o.spool)
            good_t, good_spool = self._good or (o.t, o.spool)
            self._stop_watch = (good_t, good_spool, v.reason, 'the last usable estimate')
            self._event('warn', f'tug evidence lost ({v.reason}: {v.detail}): winch stopped',
                        reason=v.reason)
        if not v.transient or o.t - self._gap[0] >= self.cfg.evidence_grace_s:
            self._abort(v, in_tug=True)

    def _abort(self, v: evidence.Verdict, in_tug: bool) -> None:
        """Record this attempt as aborted (reason code) and wait for evidence (retry policy)."""
        self._winch = 0.0
        if in_tug:
            self._finish_tug('aborted')
        self.aborts += 1
        self.cycle.outcome = 'aborted'
        self.cycle.cause, self.cycle.reason = HoldCause.EVIDENCE, v.reason
        self._record()
        self._go(State.WAIT_EVIDENCE, f'tug aborted, winch stopped: {v.reason} ({v.detail}); '
                                      f'abort {self.aborts}/{self.cfg.max_aborts}')

    def _enter_wait_evidence(self) -> None:
        self._winch = 0.0
        self._usable_since = None

    def _do_wait_evidence(self) -> None:
        cfg, o = self.cfg, self.obs
        self._winch = 0.0
        if self.aborts > cfg.max_aborts:
            self._give_up(f'{self.aborts} aborted tugs (max_aborts {cfg.max_aborts})')
            return
        if self.evidence().usable:
            if self._usable_since is None:
                self._usable_since = o.t
            if o.t - self._usable_since >= cfg.evidence_settle_s:
                mode = self.mode
                self._new_cycle()
                self.cycle.modes.append(mode)
                self._burrows = 1
                self._go(State.CHECK, f'evidence back: re-checking the {mode} anchor before '
                                      f'tugging again (cycle {self.cycle.index})')
            return
        self._usable_since = None
        if self._elapsed() >= cfg.evidence_wait_s:
            self._give_up(f'no usable capacity estimate within {cfg.evidence_wait_s:.0f} s '
                          f'(status {o.capacity_status})')

    def _give_up(self, why: str) -> None:
        self._winch = 0.0
        self._oneshots.append(('gait', 'stand'))
        self._go(State.FINISHED, f'giving up, winch braked: {why}')

    def _on_slip(self, ev: SlipEvent) -> None:
        """The anchor moved under load: stop, learn how much weaker the ground is than
        predicted, then re-burrow into a mode that is strong enough with that correction."""
        o = self.obs
        self._winch = 0.0
        self._stop_watch = (o.t, o.spool, ev.reason, 'the slip was detected')
        self._finish_tug('slip')
        predicted = o.capacity if (o.capacity is not None and math.isfinite(o.capacity)) \
            else self.own_capacity()[0]
        note = ''
        if predicted and predicted > 0 and ev.peak_tension > 0:
            k = min(1.0, ev.peak_tension / (predicted * self.chooser.scale)) * self.chooser.scale
            if k < self.chooser.scale:
                self.chooser.scale = k
                note = (f'; the anchor held {ev.peak_tension:.2f} N where {predicted:.2f} N was '
                        f'predicted: predictions scaled by {k:.2f} from now on')
        self._weakest = ev.peak_tension
        self._event('warn', f'anchor slip detected ({ev.reason}: {ev.detail}){note}',
                    reason=ev.reason, peak_tension=ev.peak_tension, scale=self.chooser.scale)
        self._hold(HoldCause.SLIP, f'anchor slip ({ev.reason}): winch stopped', ev.reason)

    def _twist_text(self) -> str:
        tw = self.obs.slip_twist
        if tw is None or not all(math.isfinite(x) for x in tw) or not any(tw):
            return '(holds: no slip predicted)'
        return f'(vx {tw[0]:+.2f}, vz {tw[1]:+.2f}, wy {tw[2]:+.2f})'

    def _finish_tug(self, outcome: str) -> None:
        c, o = self.cycle, self.obs
        dt = o.t - self._tug_start_t
        c.tug_s += dt
        if self._tug_hist:
            t_end, e_end = self._tug_hist[-1]
            e_start = self._tug_hist[0][1]
            win = [e for t, e in self._tug_hist if t >= t_end - self.cfg.tug_energy_window_s]
            c.tug_total_j += e_end - e_start
            c.tug_j += e_end - (win[0] if win else e_end)
        c.tensions.extend(self._tug_tensions)
        if outcome == 'arrived':
            med = self.need.update(self._tug_tensions)
            if med is not None:
                self._event('info', f'measured sliding tension {med:.2f} N '
                                    f'(nominal {self.need.nominal:.2f} N); required force now '
                                    f'{self.need.value:.2f} N')

    def _do_hold(self) -> None:
        self._winch = 0.0
        if self._hold_cause in REBURROW_WHY and self.cfg.reburrow:
            why = REBURROW_WHY[self._hold_cause]
            self._hold_cause = HoldCause.NONE
            self._reselect(why, self._weakest)
        elif self._elapsed() > 0.5:
            self._stop_cycle(self.reason)

    def _do_cycle_done(self) -> None:
        self.cycle.outcome = 'ok'
        self._record()
        # Aborted attempts are retried as extra cycles: count the ones that ran their course.
        if sum(r.outcome != 'aborted' for r in self.records) >= self.cfg.cycles:
            self._oneshots.append(('gait', 'stand'))
            self._go(State.FINISHED, f'{self.cfg.cycles} cycles done')
            return
        self._new_cycle()
        self._go(State.WALK, f'cycle {self.cycle.index}/{self.cfg.cycles}: unburrow by '
                             f'walking {self.cfg.walk_time_s:.1f} s')

    def _record(self) -> None:
        c = self.cycle
        xs = sorted(c.tensions)
        self.records.append(CycleRecord(
            sled_kg=self.cfg.sled_mass_kg, cycle=c.index, mode='+'.join(c.modes) or '-',
            outcome=c.outcome, walk_j=c.walk_j, burrow_j=c.burrow_j, tug_j=c.tug_j,
            tug_total_j=c.tug_total_j, walk_s=c.walk_s, burrow_s=c.burrow_s, tug_s=c.tug_s,
            distance_m=c.walk_s * self.cfg.walk_speed_m_s, sled_distance_m=c.sled_distance,
            need_n=self.need.value,
            tension_median_n=xs[len(xs) // 2] if xs else float('nan'),
            min_margin_n=c.min_margin if math.isfinite(c.min_margin) else float('nan'),
            reason=c.reason))
        self._event('cycle', self.records[-1].summary())

    def _do_wait_link(self) -> None:
        self._winch = 0.0
        if not self._inputs_fresh():
            self._link_back_at = None
            return
        if self._link_back_at is None:
            self._link_back_at = self.obs.t
            return
        if self.obs.t - self._link_back_at < self.cfg.link_settle_s:
            return
        self._link_back_at = None
        resume = self._resume or State.IDLE_MEASURE
        if resume in (State.TUG, State.HOLD, State.CHECK, State.CYCLE_DONE):
            if resume == State.TUG:
                self._finish_tug('interrupted')
            if not self._at_final_pose():
                # The legs moved during the outage (an MCU reset, a stand): the anchor that
                # was checked is gone, and the assumed Table II height no longer applies.
                self._burrow(self.mode, f'link back after {self._elapsed():.1f} s: the legs '
                                        f'left the {self.mode} pose during the outage')
                return
            self._go(State.CHECK, f'link back after {self._elapsed():.1f} s: re-checking '
                                  f'the {self.mode} anchor before resuming the tug')
        elif resume == State.WALK:
            self._go(State.WALK, f'link back after {self._elapsed():.1f} s: walking on')
        elif resume == State.BURROW:
            self._burrows -= 1
            self.cycle.modes.pop()
            self._burrow(self.mode, f'link back after {self._elapsed():.1f} s: burrow again')
        elif resume == State.SLACKEN:
            self._go(State.SLACKEN, 'link back: slacken again')
        else:
            self._go(resume, f'link back after {self._elapsed():.1f} s')

    def _at_final_pose(self) -> bool:
        legs, m = self.obs.legs, ANCHOR_MODES.get(self.mode or '')
        return m is not None and legs is not None and max(
            abs(legs[0] - m.final[0]), abs(legs[1] - m.final[1])) <= self.cfg.burrow_tolerance_rad

    @property
    def done(self) -> bool:
        return self.state in TERMINAL

    # ------------------------------------------------------------------ cancel
    def cancel(self, why: str) -> None:
        """Stop the run now (the walk-burrow-tug action's cancel): the winch braked in the
        next ``step``'s commands, the legs left where they are (a burrowed anchor keeps holding
        a taut tether), a walking robot told to stand; the cycle in progress is recorded
        ``cancelled``; FINISHED. Nothing happens once the run is over."""
        if self.done:
            return
        c = self.cycle
        if self.state == State.TUG:
            self._finish_tug('cancelled')
        elif c is not None and self.state == State.WALK:     # the walk so far counts
            c.walk_j += self._energy_since_enter()
            c.walk_s += self._elapsed()
        elif c is not None and self.state == State.BURROW:   # the burrow so far counts
            c.burrow_j += self._energy_since_enter()
            c.burrow_s += self._elapsed()
        if self.state == State.WALK or (self.state == State.WAIT_LINK
                                        and self._resume == State.WALK):
            self._oneshots.append(('gait', 'stand'))
        self._winch = 0.0
        if c is not None and not (self.records and self.records[-1].cycle == c.index):
            c.outcome, c.reason = 'cancelled', 'cancelled'
            self._record()
        self._go(State.FINISHED, f'cancelled, winch braked: {why}')
