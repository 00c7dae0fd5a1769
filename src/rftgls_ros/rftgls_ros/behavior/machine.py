"""The walk-burrow-tug state machine (paper section VI-C), without ROS.

    WAIT_INPUTS -> IDLE_MEASURE -> [ WALK -> CHOOSE -> BURROW -> CHECK -> TUG -> CYCLE_DONE ] x N
                                                 |          ^        |     |
                                                 v          |        |     v
                                              REFUSED   STEP_OFF     |    HOLD (margin guard,
                                                 (walk step_off_m)   |     |   slip, short,
                                                            ^        v     |   slow tug)
                                                            +----- SLACKEN <-+--> FINISHED
                                                                          (no stronger mode)
    CHECK, TUG --evidence lost--> WAIT_EVIDENCE --evidence back--> CHECK (next cycle)
                                       +--no evidence in time / too many aborts--> FINISHED
    any active state --link lost / inputs stale--> WAIT_LINK --back--> resume

A tug runs only on live evidence (``evidence.judge``; docs/design/tug-safety.md): without a
fresh, value-carrying, accepted estimate from capacity_node the winch is stopped in the same
step, and the attempt is recorded ``aborted`` with the reason code.

``step(obs)`` takes an ``Observation`` (SI values and their times, s) and returns the
``Commands`` to publish, with the step's events (dicts with a human ``text``: every
transition and decision), which the node logs and publishes. ``events`` keeps the recent
history for inspection.

The run is split by phase; each phase owns its state (small dataclasses) and the entry actions
and steps of its states, which the machine collects into its state table:

    walk.py       IDLE_MEASURE, WALK, STEP_OFF: the idle power at start, walking with the
                  tether paid out, stepping off the dug sand before a re-burrow
    burrow.py     CHOOSE, BURROW, CHECK, HOLD, SLACKEN: choose a mode, burrow, check the anchor
                  at the measured pose, re-burrow into a stronger mode after a stop
    tug.py        TUG: reel in on live evidence, the margin guard, the slip, the stop report
                  (the slip's references belong to the anchor: the machine's ``slip``, reset
                  by every burrow, kept through link gaps, waits and re-checks)
    retry.py      WAIT_EVIDENCE: an aborted attempt, waiting for evidence, giving up
    link_wait.py  WAIT_LINK: robot link or inputs lost, winch stopped, resume

This module holds what the phases share: the configuration and models, the observation, the
winch set-point and one-shot commands, events and transitions, the cycle tally and how a cycle
ends (its report row).
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from rftgls_core.planning.burrowed import BurrowedPose
from rftgls_core.types import AnchorState, Provenance

from ..tether import TetherTracker
from . import evidence
from .burrow import Burrow
from .config import BehaviorConfig
from .link_wait import LinkWait
from .model import (
    AnchorMode,
    Candidate,
    Decision,
    EnergyModel,
    ForceNeed,
    ModeChooser,
)
from .planned import GaitChooser, PlannedGait
from .reel import tug_ratio
from .replay import InlineReplayer
from .report import CycleRecord
from .retry import EvidenceRetry
from .signals import Commands, Observation
from .slip import SlipDetector
from .states import ACTIVE, TERMINAL, WALKING, HoldCause, State
from .tug import Tug
from .walk import Walk

EVENT_HISTORY = 10000   # events kept in BehaviorMachine.events
# States in which p sits at the burrowed mode's height (else it walks at h_walk_m).
BURROWED = {State.BURROW, State.CHECK, State.TUG, State.HOLD, State.SLACKEN, State.CYCLE_DONE,
            State.REFUSED, State.FINISHED, State.WAIT_LINK, State.WAIT_EVIDENCE}


@dataclass
class CycleTally:
    """One cycle as it runs: modes burrowed (in order), energy (J) and time (s) per phase, the
    sled's travel (m), how it ended (outcome, the CSV reason code, the hold cause), the first
    slip's reason code, the
    required force (N), the smallest margin (N) and the sliding tensions (N); the chooser's
    last pick and reason, and the smallest lower-bound margin the winch reeled in on (N)."""

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
    slip: str = ''            # the first slip's reason code (kept whatever ends the cycle)
    cause: HoldCause = HoldCause.NONE
    need_n: float = 0.0
    min_margin: float = math.inf
    tensions: list[float] = field(default_factory=list)
    choice: Candidate | None = None     # the chooser's last pick (or strongest, refused)
    decision: str = ''                  # the chooser's last reason, one line
    # Smallest (capacity_node lower bound x scale - safety_factor x need), N, over the steps
    # that commanded the winch to reel in: negative would be a tug below the need.
    reel_lower_margin: float = math.inf
    # The lower bound x scale (N) CHECK last started a tug on: capacity_node's at the measured
    # pose (NaN: no tug started).
    check_lower: float = math.nan
    plan: PlannedGait | None = None     # the planned gait chosen last ('planned' burrows)


class BehaviorMachine:
    """The behaviour. ``chooser`` answers capacity predictions (map), the rest is owned here
    and by the phases (walk, burrow, tug, retry, link)."""

    def __init__(self, config: BehaviorConfig, chooser: ModeChooser,
                 replayer: InlineReplayer | None = None):
        self.cfg = config
        self.chooser = chooser
        # Decisions are judged against the guard this machine tugs with (ModeChooser).
        chooser.stop_ratio = config.stop_ratio
        # Replays a planned burrow over its measured legs (replay.py); None: the plan's pose.
        self.replayer = replayer
        self.replayed: BurrowedPose | None = None   # the pose the replay gave this burrow
        self.pose_disagrees = False    # the measured pitch lies outside the replayed band
        self.need = ForceNeed(config.sled_mass_kg, config.sled_mu, alpha=config.need_alpha)
        self.energy = EnergyModel(prior_sh=config.energy_prior_sh_J)
        if isinstance(chooser, GaitChooser):    # energy per planned gait, not per mode
            self.energy = chooser.energy_model(self.energy)
        self.tether = TetherTracker(config.rope_length_m, config.attach_height_m)
        self.state = State.WAIT_INPUTS
        self.reason = 'waiting for the robot and capacity_node'
        self.events: deque[dict] = deque(maxlen=EVENT_HISTORY)
        self.records: list[CycleRecord] = []
        self.decisions: list[Decision] = []
        self.obs = Observation(t=0.0)
        self.cycle: CycleTally | None = None
        self.mode: str | None = None          # the mode burrowed (or being burrowed)
        self.winch = 0.0                      # reel-in set-point, m/s; held until changed
        self.winch_valid_until = 0.0          # s: when a tug's reel-in evidence runs out
        self.leg_targets: tuple[float, float] | None = None   # this step's (L1, L2), rad
        self.idle_power = 0.0                 # W, measured standing at start
        self.weakest: float | None = None     # N: the anchor's weakest capacity, or what it held
        self._oneshots: list[tuple[str, str]] = []
        self._step_events: list[dict] = []
        self._t_enter = 0.0
        self._e_enter: float | None = None
        self._last_spool: float | None = None
        # The anchor's slip evidence (slip.py): kept per burrow through gaps, waits, re-checks.
        self.slip = SlipDetector(config.slip_pitch_rad, config.slip_leg_rad,
                                 config.slip_tension_drop, config.slip_min_reel_m,
                                 config.taut_tension_N)
        self.walk = Walk(self)
        self.burrow = Burrow(self)
        self.tug = Tug(self)
        self.retry = EvidenceRetry(self)
        self.link = LinkWait(self)
        self._on_enter: dict[State, Callable[[], None]] = {}
        self._handlers: dict[State, Callable[[], None]] = {
            State.WAIT_INPUTS: self._do_wait_inputs, State.CYCLE_DONE: self._do_cycle_done,
            # REFUSED and FINISHED are terminal: nothing to do.
        }
        for phase in (self.walk, self.burrow, self.tug, self.retry, self.link):
            self._on_enter.update(phase.on_enter)
            self._handlers.update(phase.on_step)

    # ------------------------------------------------------------------ shared by the phases
    def command(self, topic: str, value: str) -> None:
        """A one-shot ``gait`` or ``burrow`` command, published after this step."""
        self._oneshots.append((topic, value))

    def event(self, kind: str, text: str, **extra) -> None:
        ev = {'t': round(self.obs.t, 3), 'kind': kind, 'state': str(self.state), 'text': text,
              **extra}
        self.events.append(ev)
        self._step_events.append(ev)

    def go(self, new: State, reason: str) -> None:
        old = self.state
        self.state = new
        self.reason = reason
        self._t_enter = self.obs.t
        self._e_enter = self.obs.energy
        self.event('transition', f'{old} -> {new}: {reason}', **{'from': str(old),
                                                                'to': str(new)})
        enter = self._on_enter.get(new)
        if enter is not None:
            enter()

    def required(self) -> float:
        """The lower bound a decision needs now, N: the chooser's rule (safety factor, margin
        guard, and the reel bringing in the tether left within the tug timeout) on the
        current required force."""
        return self.chooser.required(self.need.value)

    def elapsed(self) -> float:
        """Time in the current state, s."""
        return self.obs.t - self._t_enter

    def energy_since_enter(self) -> float:
        """Energy drawn since the current state was entered, J (0 without readings)."""
        if self.obs.energy is None or self._e_enter is None:
            return 0.0
        return self.obs.energy - self._e_enter

    @property
    def burrows(self) -> int:
        """Burrows in this cycle (its modes, re-burrows included)."""
        return len(self.cycle.modes) if self.cycle else 0

    @property
    def height(self) -> float:
        """Height of p (m) as sent (height_input): not measured on MiniRQuad; the burrow
        replayed over the measured legs, the plan's prediction, Table II's mean or h_walk_m."""
        return self.height_input()[0]

    def burrow_mode(self) -> AnchorMode | None:
        """The burrow burrowed into (or being burrowed): a Table II mode or a planned gait."""
        return self.chooser.modes.get(self.mode or '')

    def planned_gait(self) -> PlannedGait | None:
        """The planned gait burrowed into (None for a Table II mode)."""
        gaits = getattr(self.chooser, 'gaits', {})
        return gaits.get(self.mode or '')

    def height_input(self) -> tuple[float, float, str, Provenance]:
        """(h m, band m, source, provenance) of the height of p. Burrowed in a planned gait:
        the burrow simulation's predicted h within H_BAND_SDS of its standard deviations,
        modelled, replaced by the simulation over the measured legs once it is in (assumed
        when the measured pitch lies outside its band); in a Table II mode: the mode's Table
        II mean within H_BAND_SDS of its standard deviations, assumed; else h_walk_m (band
        not stated), assumed."""
        m = self.burrow_mode()
        if m is not None and self.state in BURROWED:
            h, band = self.anchor_height()
            r = self.replayed
            if r is not None:
                return h, band, f'{r.source}, not measured', (
                    Provenance.ASSUMED if self.pose_disagrees else Provenance.MODELLED)
            if self.planned_gait() is not None:
                return (h, band, f'burrow simulation of gait {m.name} (planner), '
                        'not measured', Provenance.MODELLED)
            return h, band, f'Table II mean of {m.name} (paper), not measured', \
                Provenance.ASSUMED
        return self.cfg.h_walk_m, math.nan, 'h_walk_m parameter (walking), not measured', \
            Provenance.ASSUMED

    def inputs_fresh(self) -> bool:
        """The link is up and the robot's joint states and tension are recent."""
        o = self.obs
        return (o.link_ok and o.t - o.t_legs <= self.cfg.input_timeout_s
                and o.t - o.t_tension <= self.cfg.input_timeout_s)

    def evidence(self) -> evidence.Verdict:
        """Is capacity_node's last estimate usable evidence for tugging now?"""
        o = self.obs
        return evidence.judge(o.t, o.capacity, o.capacity_status, o.t_capacity,
                              self.cfg.estimate_timeout_s, o.assumed_inputs,
                              frozenset(self.cfg.accept_assumed_inputs), o.capacity_lower,
                              o.capacity_h, None if o.height_measured else self.height)

    def decision_capacity(self) -> float:
        """What capacity_node's usable estimate lets a decision count on, N: its lower bound
        times the learned scale (call only on usable evidence)."""
        assert self.obs.capacity_lower is not None
        return self.obs.capacity_lower * self.chooser.scale

    def capacity_valid(self) -> bool:
        return self.evidence().usable

    def anchor_height(self) -> tuple[float, float]:
        """(h m, band m) of p in the burrowed mode (burrow_mode() not None): the burrow
        simulation over the measured legs once it is in, else the mode's own (the plan's
        prediction, or Table II's mean). The height sent to capacity_node (height_input) and
        the one this node's own checks judge at are this one."""
        m = self.burrow_mode()
        assert m is not None
        r = self.replayed
        return (r.h_m, r.h_band_m) if r is not None else (m.h, m.h_band)

    def measured_state(self) -> AnchorState | None:
        """The anchor state of the burrowed mode at the measured legs and pitch (leg angles
        within pose_snap_rad of the mode's final pose taken as it), h from anchor_height."""
        m = self.burrow_mode()
        if m is None or self.obs.legs is None:
            return None
        tb = self.obs.theta_b if self.obs.theta_b is not None else m.theta_b
        l1, l2 = self.obs.legs
        if abs(l1 - m.final[0]) <= self.cfg.pose_snap_rad:
            l1 = m.final[0]
        if abs(l2 - m.final[1]) <= self.cfg.pose_snap_rad:
            l2 = m.final[1]
        return AnchorState(self.anchor_height()[0], tb, l1, l2)

    def own_capacity(self) -> tuple[float | None, str]:
        """This node's map prediction (N, status) at the measured pose and estimated phi: its
        lower end over the anchor height's band."""
        state = self.measured_state()
        if state is None:
            return None, 'stale'
        cap, status = self.chooser.lower_capacity(state, self.tether.phi(self.height),
                                                  self.anchor_height()[1])
        return cap, str(status)

    # ------------------------------------------------------------------ step
    def step(self, obs: Observation) -> Commands:
        self.obs = obs
        self._track_spool(obs)
        # A decision asks for a bound the reel can bring the tether left in on (reel.py).
        self.chooser.reel_ratio = tug_ratio(self.cfg,
                                            self.tether.free_length - self.cfg.arrive_length_m)
        if self.state in ACTIVE and not self.inputs_fresh():
            self.link.interrupt()
        handler = self._handlers.get(self.state)
        if handler is not None:
            handler()
        self.tug.report_stop()
        self._track_reel_basis()
        h, band, source, provenance = self.height_input()
        valid = self.winch_valid_until if self.state == State.TUG and self.winch > 0.0 else 0.0
        out = Commands(self._oneshots, self.winch, h, self.tether.phi(h), self._step_events,
                       band, source, provenance, self.leg_targets, valid,
                       self.state in WALKING)
        self._oneshots, self._step_events, self.leg_targets = [], [], None
        return out

    def taut(self) -> bool:
        """The measured tension has reached taut_tension_N: the rope pulls."""
        return (self.obs.tension or 0.0) >= self.cfg.taut_tension_N

    def _track_spool(self, obs: Observation) -> None:
        """Tether paid out / reeled in from the spool encoder; while a taut tug reels in, the
        sled's travel."""
        if obs.spool is None or obs.spool == self._last_spool:
            return
        if self._last_spool is not None and self.state == State.TUG and self.cycle \
                and self.taut():
            d = obs.spool - self._last_spool
            if 0.0 < d < 0.2:
                self.cycle.sled_distance += d
        self.tether.update(obs.spool)
        self._last_spool = obs.spool

    def _track_reel_basis(self) -> None:
        """Book what the winch reels in on this step: capacity_node's lower bound (x the
        learned scale) against safety_factor x need (without the guard's share: the margin a
        reel-in really had). Kept apart from the tug's own checks, so
        the report shows whether a tug ever ran below its need."""
        c, o = self.cycle, self.obs
        if c is None or self.winch <= 0.0 or self.burrow.taking_up:
            return      # a burrow's take-up reels in only to taut_tension_N: no load
        lower = o.capacity_lower
        basis = lower * self.chooser.scale if lower is not None and math.isfinite(lower) \
            else -math.inf
        c.reel_lower_margin = min(c.reel_lower_margin,
                                  basis - self.cfg.safety_factor * self.need.value)

    def _do_wait_inputs(self) -> None:
        if self.inputs_fresh() and self.obs.energy is not None:
            self.go(State.IDLE_MEASURE, 'robot link ok, sensors fresh')

    # ------------------------------------------------------------------ cycles
    def new_cycle(self) -> None:
        idx = 1 if self.cycle is None else self.cycle.index + 1
        self.cycle = CycleTally(idx)

    def decide(self, d: Decision) -> None:
        """Keep and announce a mode decision (with its candidate table)."""
        self.decisions.append(d)
        c = self.cycle
        gait = getattr(self.chooser, 'gaits', {}).get(d.mode or '')
        extra = {'plan': gait.report(self.cfg.phis_rad)} if gait is not None else {}
        if c is not None:
            c.plan = gait or c.plan
            c.decision = d.reason
            if d.mode:
                c.choice = d.candidate(d.mode)
            elif not c.modes:        # refused before any burrow: the strongest it had
                c.choice = max((x for x in d.candidates if x.weakest is not None),
                               key=lambda x: x.weakest, default=None)
        self.event('decision', f'decision ({d.pose} pose): {d.reason}\n{d.table()}',
                   mode=d.mode, need_n=d.need_n, required_n=d.required_n, tug_ratio=d.tug_ratio,
                   candidates=[{'mode': c.mode, 'capacities': c.capacities,
                                'statuses': c.statuses, 'energy_j': c.energy_j,
                                'sufficient': c.sufficient, 'why': c.why}
                               for c in d.candidates], **extra)

    def record(self) -> None:
        """The cycle's report row (and its summary event)."""
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
            reason=c.reason, slip=c.slip,
            lower_n=_num(c.choice.weakest if c.choice else None),
            point_n=_num(c.choice.point if c.choice else None),
            energy_pred_j=_num(c.choice.energy_j if c.choice else None),
            reel_lower_margin_n=_num(c.reel_lower_margin), check_lower_n=c.check_lower,
            decision=c.decision,
            **plan_columns(c.plan)))
        r = self.records[-1]
        self.event('cycle', r.summary(), cycle=r.cycle, outcome=r.outcome, reason=r.reason,
                   slip=r.slip)

    def _do_cycle_done(self) -> None:
        self.cycle.outcome = 'ok'
        self.record()
        # Aborted attempts are retried as extra cycles: count the ones that ran their course.
        if sum(r.outcome != 'aborted' for r in self.records) >= self.cfg.cycles:
            # The robot stays burrowed: the braked winch holds the sled's sliding tension,
            # and legs swung out of the sand under it would let the sled drag the robot.
            self.winch = 0.0
            self.go(State.FINISHED, f'{self.cfg.cycles} cycles done; the anchor holds the '
                                    'sled, winch braked')
            return
        self.new_cycle()
        self.go(State.WALK, f'cycle {self.cycle.index}/{self.cfg.cycles}: unburrow by '
                            f'walking {self.cfg.walk_time_s:.1f} s')

    def refuse(self, reason: str) -> None:
        """No mode suffices: no tug at all (REFUSED, winch braked, standing)."""
        self.winch = 0.0
        self.command('gait', 'stand')
        if self.cycle:
            self.cycle.outcome, self.cycle.reason = 'refused', 'no_sufficient_mode'
            self.record()
        self.go(State.REFUSED, f'not tugging: {reason}')

    def stop_cycle(self, reason: str) -> None:
        """The cycle cannot go on safely: record it stopped and finish, winch braked."""
        self.winch = 0.0
        self.cycle.outcome = 'stopped'
        self.record()
        what = 'stopped after a slip' if self.cycle.cause is HoldCause.SLIP \
            else 'stopped before slip'
        self.go(State.FINISHED, f'{what}, winch braked: {reason}')

    def close(self, reason: str) -> None:
        """The run ends here (the node stops, a link that never came back): winch braked, and
        a cycle still in progress gets its row, ``aborted`` with ``reason`` (the wait it was
        in, e.g. link_stale), so that no cycle goes unreported."""
        self.winch = 0.0
        c = self.cycle
        if c is None or self.done or (self.records and self.records[-1].cycle == c.index):
            return
        c.outcome, c.reason = 'aborted', reason
        if self.state == State.TUG:
            self.tug.finish('aborted')
        self.record()

    def open_reason(self) -> str:
        """The reason code a cycle cut off now would be recorded with."""
        if self.state == State.WAIT_LINK:
            return self.link.reason()
        if self.state == State.WAIT_EVIDENCE:
            return self.cycle.reason if self.cycle and self.cycle.reason else 'no_evidence'
        return 'shutdown'

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
            self.tug.finish('cancelled')
        elif c is not None and self.state in WALKING:     # the walk so far counts
            self.walk.pause()
        elif c is not None and self.state == State.BURROW:   # the burrow so far counts
            c.burrow_j += self.energy_since_enter()
            c.burrow_s += self.elapsed()
        if self.state in WALKING or (self.state == State.WAIT_LINK
                                     and self.link.resume in WALKING):
            self.command('gait', 'stand')
        self.winch = 0.0
        if c is not None and not (self.records and self.records[-1].cycle == c.index):
            c.outcome, c.reason = 'cancelled', 'cancelled'
            self.record()
        self.go(State.FINISHED, f'cancelled, winch braked: {why}')


def _num(x: float | None) -> float:
    """A report number: NaN for None or infinite (nothing measured)."""
    return x if x is not None and math.isfinite(x) else float('nan')


def plan_columns(gait: PlannedGait | None) -> dict:
    """The report's columns of a planned gait (NaN for a Table II mode): its predicted h and
    one sigma (m), predicted pitch (rad) and the probability that it holds."""
    if gait is None:
        return {}
    a = gait.answer
    return {'h_pred_m': float(a.pose[0]), 'h_pred_sigma_m': float(a.pose_sigma[0]),
            'theta_b_pred_rad': float(a.pose[1]), 'p_hold': gait.p_hold}
