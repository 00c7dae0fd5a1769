"""The anchor: choose a burrowing mode, burrow, check the anchor at the measured pose, and after
a stop re-burrow into a stronger mode (CHOOSE, BURROW, CHECK, HOLD, SLACKEN).

The choice and the checks ask the ModeChooser (the lower bound over a mode's height band at its
pose for every tether angle of ``phis_rad``, the cheapest sufficient mode in energy). The pose
check uses the measured leg angles and pitch, and h from Table II (MiniRQuad does not measure
it) only while the legs are at the mode's final pose (else the mode is burrowed again); the tug
then starts only on capacity_node's live evidence (``machine.evidence``), its
lower bound against the need. A re-check at a pose within the slip thresholds of the anchor's
last sufficient check keeps that check (``_still_passed``). At most ``max_burrows_per_cycle``
burrows per cycle. Units: m, rad, N, J, s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rftgls_core.planning.gaits import STAND
from rftgls_core.planning.replay import BurrowRecord
from rftgls_core.types import AnchorState, Status

from . import evidence
from .gait_motion import RAMP_LEAD_S, RampClock, gait_duration, gait_targets, leg_span, stand_time
from .model import versus
from .states import REBURROW_WHY, HoldCause, State

# Longest a planned burrow's ramp waits for the measured legs, at standing or anywhere along
# it (s): servos at a few degrees of lag arrive in tens of ms; legs held by the sand, or a
# stalled servo, must not stall the burrow (its timeout and the replay's check still apply).
LEG_WAIT_S = 1.0
# s the legs stay within burrow_tolerance_rad of standing before the burrow proper starts:
# legs at rest there, not passing through (a walk the MCU has not stopped yet turns them at
# ~300 deg/s, within 3 deg of standing for ~20 ms).
STAND_SETTLE_S = 0.1

if TYPE_CHECKING:
    from .machine import BehaviorMachine


@dataclass
class AnchorCheck:
    """CHECK's progress: the prediction at the measured pose said sufficient (why), or the
    query went unanswered (warned once); since when (s) the height it checks is settled (the
    replay done), from which its waits for capacity_node count."""

    passed: bool = False
    why: str = ''
    unanswered: bool = False
    settled_since: float | None = None


@dataclass(frozen=True)
class PassedCheck:
    """A prediction check that said sufficient: the anchor (mode), the measured state it was
    made at, the need and slip scale it was judged against, and why."""

    mode: str
    state: AnchorState
    need_n: float
    scale: float
    why: str


@dataclass(frozen=True)
class Reburrow:
    """The mode to burrow into once the tether is slack, and why."""

    mode: str
    reason: str


@dataclass
class TakeUp:
    """A burrow's take-up of the slack (Burrow._rope_ready). t0: s (node clock) it started,
    None before; e0: energy then, J; seconds, joules: its length and the energy it drew."""

    done: bool = False
    t0: float | None = None
    e0: float | None = None
    seconds: float = 0.0
    joules: float = 0.0


class Burrow:
    """CHOOSE, BURROW, CHECK, HOLD and SLACKEN."""

    def __init__(self, machine: BehaviorMachine):
        self.m = machine
        self.at_pose_since: float | None = None   # s (leg sample time): legs at the final pose
        self.legs_from: tuple[float, float] | None = None   # planned gait: legs at its start
        self.ramp = RampClock(0.0, LEG_WAIT_S)  # planned gait: time along its ramp
        self.target: tuple[float, float] | None = None   # the ramp's last leg targets, rad
        self.stand_reached: float | None = None  # s: the ramp reached standing (node clock)
        self.at_stand_since: float | None = None   # s: legs within tolerance of standing
        self.record_from: float | None = None   # s: the burrow proper started (None: not yet)
        self.take_up = TakeUp()                 # this burrow's take-up of the slack
        self.commanded = False                  # a Table II mode's burrow command went out
        self.check = AnchorCheck()
        self.passed: PassedCheck | None = None     # this anchor's last sufficient check
        self.choose_unanswered = False             # CHOOSE's questions unanswered (warned)
        self.hold_cause = HoldCause.NONE
        self.next: Reburrow | None = None
        self.record: list[tuple[float, float, float]] = []   # (t, L1, L2) measured, s, rad
        self.replay_since: float | None = None     # s: the burrow's replay was submitted
        self.replayed_from: tuple[float, ...] = (math.nan, math.nan)   # legs it starts at
        self.on_enter = {State.BURROW: self._enter_burrow, State.CHECK: self._enter_check,
                         State.SLACKEN: self._enter_slacken}
        self.on_step = {State.CHOOSE: self._do_choose, State.BURROW: self._do_burrow,
                        State.CHECK: self._do_check, State.HOLD: self._do_hold,
                        State.SLACKEN: self._do_slacken}

    # ------------------------------------------------------------------ choose and burrow
    def _do_choose(self) -> None:
        m = self.m
        d = m.chooser.choose(m.need.value, m.energy)
        if d.mode is None and m.elapsed() < m.cfg.evidence_wait_s and all(
                s == str(Status.STALE) for c in d.candidates for s in c.statuses):
            # Every question unanswered (capacity_node not up yet, or busy): missing
            # evidence, not a weak ground. Wait for it, winch braked, as CHECK does.
            if not self.choose_unanswered:
                self.choose_unanswered = True
                m.event('warn', 'choose: the capacity query is unanswered (stale); waiting '
                                f'up to {m.cfg.evidence_wait_s:.0f} s before refusing')
            return
        self.choose_unanswered = False
        m.decide(d)
        if d.mode is None:
            m.refuse(d.reason)
        else:
            self.start(d.mode, d.reason)

    def start(self, mode: str, reason: str) -> None:
        """Burrow into `mode` (one more burrow this cycle)."""
        m = self.m
        m.mode = mode
        m.cycle.modes.append(mode)
        m.go(State.BURROW, f'burrow {mode}: {reason.split(";")[0]}')

    def _enter_burrow(self) -> None:
        m = self.m
        m.winch = 0.0
        self.take_up = TakeUp(done=m.cfg.take_up_max_s <= 0.0)
        self.commanded = False
        self.at_pose_since = None
        self.passed = None      # a new anchor is checked afresh
        m.slip.reset()          # a new anchor: its slip references start afresh
        self.record, self.replay_since = [], None
        m.replayed, m.pose_disagrees = None, False
        if m.replayer is not None:
            m.replayer.cancel()
        g = m.planned_gait()
        if g is None:
            self._command_table_mode()
            return
        # A planned gait: this node streams its leg targets (gait_motion.py) from here.
        self.legs_from, self.target = m.obs.legs, None
        self.ramp = RampClock(g.speed * RAMP_LEAD_S, LEG_WAIT_S)
        self.stand_reached = self.at_stand_since = self.record_from = None
        self._drive_gait()

    def _command_table_mode(self) -> None:
        """A Table II mode: the MCU runs its sequence, once the rope is taut."""
        if not self.commanded and self._rope_ready():
            self.m.command('burrow', self.m.mode)
            self.commanded = True

    @property
    def taking_up(self) -> bool:
        """In BURROW, reeling in the slack before the burrow's stroke."""
        return (self.m.state == State.BURROW and self.take_up.t0 is not None
                and not self.take_up.done)

    def _rope_ready(self) -> bool:
        """Take up the slack before the burrow's stroke: reel in at take_up_speed_m_s until
        the tension reaches taut_tension_N (the rope the plans simulate: just taut), for at
        most take_up_max_s, after which the stroke starts anyway and says so. True once
        done; the winch is then braked."""
        m, cfg, tu = self.m, self.m.cfg, self.take_up
        if tu.done:
            return True
        o = m.obs
        if tu.t0 is None:
            tu.t0, tu.e0 = o.t, o.energy
        waited = o.t - tu.t0
        if not m.taut() and waited < cfg.take_up_max_s:
            m.winch = cfg.take_up_speed_m_s
            return False
        m.winch = 0.0
        tu.done, tu.seconds = True, waited
        if o.energy is not None and tu.e0 is not None:
            tu.joules = o.energy - tu.e0
        if m.taut():
            m.event('info', f'tether taut ({o.tension:.2f} N) after {waited:.1f} s of '
                            f'take-up: burrowing {m.mode}')
        else:
            m.event('warn', f'tether still slack after {waited:.1f} s of take-up '
                            f'({o.tension or 0.0:.2f} N): burrowing {m.mode} on a slack rope, '
                            'which the plans do not simulate')
        return True

    def _drive_gait(self) -> None:
        """This step's leg targets of the planned gait being burrowed, along the ramp's own
        clock (RampClock). The ramp holds the standing pose until the legs rest there (within
        burrow_tolerance_rad for STAND_SETTLE_S, at most LEG_WAIT_S after the ramp got there)
        and the rope is taut: the plan simulated its burrow from standing at rest, and legs
        that lag the ramp (the walk left them behind their hips) would otherwise turn toward
        the retracting pose short of it, into a burrow the plan did not simulate. The burrow
        proper, which the replay follows, starts there; from there on the ramp runs at most
        RAMP_LEAD_S of itself ahead of the measured legs (for at most LEG_WAIT_S at once)."""
        m, g = self.m, self.m.planned_gait()
        if g is None or self.legs_from is None:
            return
        now, t_stand = m.obs.t, stand_time(self.legs_from, g.speed)
        proper = self.record_from is not None
        t = self.ramp.advance(now, m.obs.legs, self.target if proper else None)
        if not proper and t >= t_stand:
            self.ramp.t = t = t_stand
            if self.stand_reached is None:
                self.stand_reached = now
            settled = self.at_stand_since is not None \
                and now - self.at_stand_since >= STAND_SETTLE_S
            if (settled or now - self.stand_reached >= LEG_WAIT_S) and self._rope_ready():
                self.record_from = self.at_stand_since if settled else now
                if not settled:     # the ramp has waited for these legs since standing
                    self.ramp.lagging_since = self.stand_reached
        self.target = gait_targets(t, self.legs_from, g.retract, g.final, g.speed)
        m.leg_targets = self.target

    def _track_stand(self, samples: list[tuple[float, float, float]]) -> None:
        """Since when (s) every measured sample (t, L1, L2) was within burrow_tolerance_rad of
        standing; None after one that was not."""
        tol = self.m.cfg.burrow_tolerance_rad
        for t, a, b in samples:
            if leg_span((a, b), STAND) > tol:
                self.at_stand_since = None
            elif self.at_stand_since is None:
                self.at_stand_since = t

    def _legs_at(self, pose: tuple[float, float]) -> bool:
        """The measured legs are within burrow_tolerance_rad of pose (rad, per axle)."""
        legs = self.m.obs.legs
        return legs is not None and leg_span(legs, pose) <= self.m.cfg.burrow_tolerance_rad

    def at_final_pose(self) -> bool:
        """The measured legs are within burrow_tolerance_rad of the mode's final pose."""
        mode = self.m.burrow_mode()
        return mode is not None and self._legs_at(mode.final)

    def _ramp_done(self) -> bool:
        """A planned gait's ramp has run to its final pose (the burrow proper started and
        ran its course); a Table II mode's sequence is the MCU's own: True."""
        g = self.m.planned_gait()
        if g is None:
            return True
        return self.record_from is not None and self.legs_from is not None and \
            self.ramp.t >= gait_duration(self.legs_from, g.retract, g.final, g.speed)

    def _do_burrow(self) -> None:
        m, cfg = self.m, self.m.cfg
        if m.planned_gait() is None:
            self._command_table_mode()
            if not self.commanded:
                return
        o = m.obs
        if m.planned_gait() is not None and o.legs is not None:
            samples = o.leg_samples + [(o.t_legs, *o.legs)]
            self._record_legs(samples)
            if self.record_from is None:
                self._track_stand(samples)
        self._drive_gait()
        # At the final pose once the burrow has run to it, for burrow_settle_s of the robot's
        # own samples: legs whose stream stalls settle nowhere. (A walk's stance sweeps the
        # legs through -20 deg, the final pose of several gaits: legs a walk left there, their
        # stream late under load, would otherwise end a burrow before it began.)
        at = self.at_final_pose() and self._ramp_done()
        if at and self.at_pose_since is None:
            self.at_pose_since = o.t_legs
        elif not at:
            self.at_pose_since = None
        done = at and o.t_legs - self.at_pose_since >= cfg.burrow_settle_s
        # the burrow's own time and energy: the take-up is the winch's, not the legs'
        dt = m.elapsed() - self.take_up.seconds
        timeout = dt >= cfg.burrow_timeout_s
        if done or timeout:
            de = m.energy_since_enter() - self.take_up.joules
            m.cycle.burrow_j += de
            m.cycle.burrow_s += dt
            above_idle = de - m.idle_power * dt
            shown = [m.mode] if m.planned_gait() is not None else list(m.energy.ratios)
            if self._table_pose_missed():
                # A Table II mode's energy is that of its whole sequence: a burrow short of
                # its final pose is no sample of it (CHECK burrows it again).
                learnt = 'not counted: the legs are not at its final pose'
            else:
                m.energy.update(m.mode, above_idle)
                learnt = 'energy estimates now ' + ', '.join(
                    f'{k} {m.energy.estimate(k):.2f} J' for k in shown)
            m.event('info', f'burrow {m.mode}: {de:.2f} J in {dt:.1f} s '
                            f'({above_idle:.2f} J above idle); {learnt}',
                    mode=m.mode, energy_j=above_idle)
            self._submit_replay()
            m.go(State.CHECK, 'at the final pose' if done else
                 f'burrow timeout ({cfg.burrow_timeout_s:.0f} s): checking the pose reached')

    def _record_legs(self, samples: list[tuple[float, float, float]]) -> None:
        """Append the samples (t, L1, L2) taken after the last one recorded, in time order
        (the newest sample comes twice: in leg_samples and as the latest legs)."""
        for sample in samples:
            if not self.record or sample[0] > self.record[-1][0]:
                self.record.append(sample)

    # ------------------------------------------------------------------ the burrowed pose
    def _submit_replay(self) -> None:
        """A planned burrow's measured legs go to the replay (replay.py); CHECK waits for it."""
        m, g = self.m, self.m.planned_gait()
        if m.replayer is None or g is None:
            return
        # The planned burrow proper starts where the measured legs rested at the standing
        # pose (_drive_gait), nearest it: replayed from there on, as the plan simulated it.
        start = -math.inf if self.record_from is None else self.record_from
        record = BurrowRecord.from_standing([s for s in self.record if s[0] >= start])
        m.replayer.submit(record, g.pose)
        self.replayed_from = record.dofs[0] if record.dofs else (math.nan, math.nan)
        self.replay_since = m.obs.t

    def _replay_done(self) -> bool:
        """False while the replay of this burrow runs (up to replay_timeout_s). Its pose
        then replaces the plan's as the height sent; a measured pitch further than
        pitch_check_tolerance_rad outside its band makes the height assumed (the burrow did
        not go as modelled: capacity_node's estimate is then not evidence). Without a
        replayed pose the plan's stands, said in an event."""
        m = self.m
        if self.replay_since is None or m.replayer is None:
            return True
        r = m.replayer.result()
        if r is None and m.obs.t - self.replay_since < m.cfg.replay_timeout_s:
            return False
        self.replay_since = None
        if r is None or r.pose is None:
            m.replayer.cancel()
            why = r.reason if r is not None else f'over {m.cfg.replay_timeout_s:g} s'
            m.event('warn', f'burrow {m.mode}: no pose from the measured legs ({why}); the '
                            "plan's predicted pose stands", mode=m.mode)
            return True
        pose, plan = r.pose, m.planned_gait()
        m.replayed = pose
        tb = m.obs.theta_b
        off = pose.pitch_disagreement(tb) if tb is not None else None
        if off is not None and off <= m.cfg.pitch_check_tolerance_rad:
            off = None                  # within what the IMU can tell apart
        m.pose_disagrees = off is not None
        text = (f'burrow {m.mode} replayed over {r.samples} measured leg samples from '
                f'({math.degrees(self.replayed_from[0]):.1f}, '
                f'{math.degrees(self.replayed_from[1]):.1f}) deg: h '
                f'{1e3 * pose.h_m:.1f} +- {1e3 * pose.h_band_m:.1f} mm, pitch '
                f'{math.degrees(pose.theta_b_rad):.1f} +- '
                f'{math.degrees(pose.theta_b_band_rad):.1f} deg')
        if plan is not None:
            text += (f' (plan: h {1e3 * plan.pose.h_m:.1f} mm, pitch '
                     f'{math.degrees(plan.pose.theta_b_rad):.1f} deg)')
        if tb is not None:
            text += f'; pitch measured {math.degrees(tb):.1f} deg'
        if off is not None:
            text += (f', {math.degrees(off):.1f} deg outside the band: the burrow did not go '
                     'as modelled, the height is sent assumed')
        m.event('warn' if off is not None else 'info', text, mode=m.mode,
                h_replay_m=pose.h_m, theta_b_replay_rad=pose.theta_b_rad, x_replay_m=r.x_m)
        return True

    # ------------------------------------------------------------------ check
    def _enter_check(self) -> None:
        self.m.winch = 0.0
        self.check = AnchorCheck()

    def _do_check(self) -> None:
        m = self.m
        if m.tug.anchor_slipped('at the re-check'):
            return
        if not self._replay_done():
            return
        if self.check.settled_since is None:
            self.check.settled_since = m.obs.t
        if not self.check.passed and not self._still_passed():
            self._check_prediction()
            return
        # The prediction holds; the tug starts only on capacity_node's live evidence.
        v = m.evidence()
        if not v.usable:
            if self._waited() >= m.cfg.capacity_wait_s:
                m.retry.abort(v, in_tug=False)
            return
        cap = m.decision_capacity()
        m.chooser.observe(m.mode, m.obs.capacity_lower)
        required = m.required()
        if cap < required:
            m.event('decision', f'capacity_node: {m.mode} holds {versus(cap, required)} '
                                'required (lower bound)', mode=m.mode)
            self.reselect(f'{m.mode} insufficient per capacity_node', cap)
            return
        m.cycle.check_lower = cap
        m.go(State.TUG, f'{m.mode} holds at the measured pose ({self.check.why}; '
                        f'capacity_node lower bound {versus(cap, required)})')

    def _waited(self) -> float:
        """s CHECK has waited for capacity_node since the height it checks settled: not since
        CHECK began, because the replay before can take seconds on a busy robot (as long as
        capacity_wait_s in a demo run) and the height it settles is new to capacity_node."""
        assert self.check.settled_since is not None
        return self.m.obs.t - self.check.settled_since

    def _still_passed(self) -> bool:
        """A re-check (after a link gap, an evidence wait or an aborted tug) of an anchor
        whose measured pose has not moved beyond the slip thresholds since its last sufficient
        check, against the same need and slip scale: that check's answer stands, and CHECK
        goes on to capacity_node's live evidence at the pose as it is now. Asking the query
        service again would block this node's step for a round of questions per re-check; under
        CPU load that block alone let its inputs age past input_timeout_s, and every re-check
        then ended in another link wait."""
        m, p = self.m, self.passed
        state = m.measured_state()
        if p is None or state is None or p.mode != m.mode or p.need_n != m.need.value \
                or p.scale != m.chooser.scale:
            return False
        if abs(state.theta_b - p.state.theta_b) > m.cfg.slip_pitch_rad or max(
                abs(state.theta_l1 - p.state.theta_l1),
                abs(state.theta_l2 - p.state.theta_l2)) > m.cfg.slip_leg_rad:
            return False
        self.check.passed = True
        self.check.why = f'{p.why}; pose unchanged since that check'
        return True

    def _check_prediction(self) -> None:
        m = self.m
        state = m.measured_state()
        if state is None:
            return
        if self._table_pose_missed():
            self._burrow_missed_table_pose(state)
            return
        c = m.chooser.evaluate(m.mode, state, m.need.value, m.energy.estimate(m.mode),
                               m.anchor_height()[1])
        m.weakest = c.weakest
        if not c.sufficient and all(s == str(Status.STALE) for s in c.statuses):
            self._check_missing_evidence()
            return
        pose = (f'measured pose thetaL1 {math.degrees(state.theta_l1):.1f}, thetaL2 '
                f'{math.degrees(state.theta_l2):.1f}, thetaB {math.degrees(state.theta_b):.1f} '
                f'deg, h {1e3 * state.h:.0f} mm ({m.height_input()[2]})')
        caps = '/'.join(f'{x:.2f}' if x is not None else s
                        for x, s in zip(c.capacities, c.statuses))
        m.event('decision', f'check {m.mode} at the {pose}: lower bound {caps} N -> '
                            f'{"sufficient" if c.sufficient else "insufficient"} '
                            f'({c.why})', mode=m.mode, capacities=c.capacities)
        if c.sufficient:
            self.check.passed, self.check.why = True, c.why
            self.passed = PassedCheck(m.mode, state, m.need.value, m.chooser.scale, c.why)
            self._do_check()
            return
        if c.weakest is not None and m.chooser.scale > 0.0:   # kept for later plans
            m.chooser.observe(m.mode, c.weakest / m.chooser.scale)
        self.reselect(f'{m.mode} insufficient at the measured pose', c.weakest)

    def _table_pose_missed(self) -> bool:
        """A Table II mode whose measured legs are not at its final pose: Table II's height
        (and its energy) belong to that pose only."""
        return self.m.planned_gait() is None and not self.at_final_pose()

    def _burrow_missed_table_pose(self, state: AnchorState) -> None:
        """A Table II mode whose legs are not at its final pose (its burrow timed out short of
        it, or something moved them): Table II's height is the height of that pose, so the
        anchor the legs are in is unknown, and no check at the assumed height is evidence.
        Slacken and burrow the mode again while the cycle has burrows left (a planned gait
        needs none of this: its replay gives the pose the measured legs reached)."""
        m, mode = self.m, self.m.burrow_mode()
        assert mode is not None
        off = leg_span((state.theta_l1, state.theta_l2), mode.final)
        why = f'{m.mode} did not reach its final pose'
        m.event('warn', f'check {m.mode}: legs measured at '
                        f'{math.degrees(state.theta_l1):.1f}, '
                        f'{math.degrees(state.theta_l2):.1f} deg, {math.degrees(off):.1f} deg '
                        f'from its final pose ({math.degrees(mode.final[0]):.1f}, '
                        f'{math.degrees(mode.final[1]):.1f} deg; tolerance '
                        f'{math.degrees(m.cfg.burrow_tolerance_rad):.1f} deg): Table II\'s '
                        'height belongs to that pose, the anchor here is unknown',
                mode=m.mode)
        if m.burrows >= m.cfg.max_burrows_per_cycle:
            m.stop_cycle(f'{why}; {m.burrows} burrows this cycle, giving up')
            return
        self.again(why)

    def again(self, why: str) -> None:
        """Burrow this mode again, as every re-burrow: slacken, step off the sand its legs
        dug (walk.py), burrow."""
        m = self.m
        self.next = Reburrow(m.mode, f'{why}; burrowing it again')
        m.go(State.SLACKEN, f'{why}: slacken the tether, then burrow {m.mode} again')

    @property
    def dug(self) -> bool:
        """The burrow under way has moved its legs into the sand: a planned gait's burrow
        proper started, or a Table II mode's command went to the MCU."""
        if self.m.planned_gait() is None:
            return self.commanded
        return self.record_from is not None

    def _check_missing_evidence(self) -> None:
        """The pose check's questions came back `stale` (capacity_node's query service
        unanswered): evidence is missing, the anchor is not shown insufficient. The evidence
        rule decides, as in the live check: wait, then abort and retry by the policy."""
        m = self.m
        if not self.check.unanswered:
            self.check.unanswered = True
            m.event('warn', f'check {m.mode}: the capacity query is unanswered (stale); '
                            'waiting for evidence, not re-burrowing', mode=m.mode)
        if self._waited() >= m.cfg.capacity_wait_s:
            v = m.evidence()
            m.retry.abort(v if not v.usable else evidence.Verdict(
                False, evidence.NO_VALUE, True, 'capacity query unanswered'), in_tug=False)

    # ------------------------------------------------------------------ after a stop
    def hold(self, cause: HoldCause, text: str, reason: str) -> None:
        """Winch stopped for `cause` (HOLD); `reason` is the cycle's CSV reason code."""
        self.hold_cause = cause
        self.m.cycle.cause, self.m.cycle.reason = cause, reason
        self.m.go(State.HOLD, text)

    def _do_hold(self) -> None:
        m = self.m
        m.winch = 0.0
        if self.hold_cause in REBURROW_WHY and m.cfg.reburrow:
            why = REBURROW_WHY[self.hold_cause]
            self.hold_cause = HoldCause.NONE
            self.reselect(why, m.weakest)
        elif m.elapsed() > 0.5:
            m.stop_cycle(m.reason)

    def reselect(self, why: str, weakest: float | None) -> None:
        """A mode stronger than `weakest` (N) if one suffices and the cycle has burrows left:
        slacken, then burrow it; else stop the cycle."""
        m = self.m
        if m.burrows >= m.cfg.max_burrows_per_cycle:
            m.stop_cycle(f'{why}; {m.burrows} burrows this cycle, giving up')
            return
        d = m.chooser.choose(m.need.value, m.energy, exclude=[m.mode],
                             stronger_than=weakest, pose='expected')
        m.decide(d)
        if d.mode is None:
            m.stop_cycle(f'{why}; {d.reason}')
        else:
            self.next = Reburrow(d.mode, f'{why}; re-burrow: {d.reason}')
            m.go(State.SLACKEN, f'{why}: slacken the tether, then re-burrow {d.mode}')

    def _enter_slacken(self) -> None:
        self.m.winch = -self.m.cfg.slacken_speed_m_s

    def _do_slacken(self) -> None:
        """Pay out for at least slacken_time_s and until the tension is below taut_tension_N
        (a heavy sled stretches the rope further than the minimum pays out, and a burrow under
        a taut tether drags the robot), at most slacken_max_s."""
        m, cfg = self.m, self.m.cfg
        if m.elapsed() >= cfg.slacken_max_s or (m.elapsed() >= cfg.slacken_time_s
                                                and not self.m.taut()):
            m.winch = 0.0
            if cfg.step_off_m > 0.0:
                m.walk.step_off(f'slackened: re-burrow {self.next.mode}')
            else:
                self.start_next()

    def start_next(self) -> None:
        """Burrow the re-burrow chosen before the slacken (`next`)."""
        assert self.next is not None
        self.start(self.next.mode, self.next.reason)
