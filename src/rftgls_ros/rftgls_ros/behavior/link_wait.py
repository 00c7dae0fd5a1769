"""Link wait (WAIT_LINK): the robot's link went stale or untrusted (the bridge counts at least
10 % of the MCU's frames lost), or its joint states / tension aged past ``input_timeout_s``, in
an active state. A tug so stopped leaves its reason code (link_stale, link_untrusted) in the
cycle's row. The winch stops in that step (a walk also stands: its payout stopped with the
winch) and the machine waits; once the inputs have been fresh for ``link_settle_s`` it resumes
where it was: a tug, hold, check or finished cycle first measures the anchor against its slip
references (a slip during the outage is recorded and answered by the slip policy, never
forgotten), then re-checks it (or burrows again if the legs left the burrowed pose during the
outage), a walk or a step off walks on for what is left, a burrow burrows again (after a
slacken and a step off, as any re-burrow, once its legs had dug). Units: s.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from . import evidence
from .states import WALKING, State

if TYPE_CHECKING:
    from .machine import BehaviorMachine


class LinkWait:
    """WAIT_LINK, and the interruption that leads there."""

    def __init__(self, machine: BehaviorMachine):
        self.m = machine
        self.resume: State | None = None        # the state the outage interrupted
        self.back_since: float | None = None     # s: inputs fresh again without a break
        self.on_enter: dict = {}
        self.on_step = {State.WAIT_LINK: self._do_wait_link}

    def interrupt(self) -> None:
        """Inputs lost in an active state: book a walk so far, stop the winch, wait."""
        m = self.m
        if m.state in WALKING:
            # The MCU runs the gait on its own: with the payout stopped a walk that went on
            # would drag the tether (and the sled, or the robot back over the sand).
            m.walk.pause()
            m.command('gait', 'stand')
        self.resume = m.state
        m.winch = 0.0
        reason = self.reason()
        if m.state == State.TUG:
            m.tug.interrupted(reason)
            # The row says why its tug stopped: the link, rather than the estimates that aged
            # with it (a slip or an abort recorded before is kept).
            if m.cycle is not None and (not m.cycle.reason
                                        or m.cycle.reason in evidence.TRANSIENT_REASONS):
                m.cycle.reason = reason
        what = m.obs.link_detail if not m.obs.link_ok else 'joint_states/tension stale'
        m.go(State.WAIT_LINK, f'{what} during {self.resume}: winch stopped, waiting')

    def reason(self) -> str:
        """The reason code of the outage: the bridge's (link_stale, link_untrusted), or
        link_stale when the robot's own inputs aged."""
        return self.m.obs.link_fault if not self.m.obs.link_ok else 'link_stale'

    def _do_wait_link(self) -> None:
        m = self.m
        m.winch = 0.0
        if not m.inputs_fresh():
            self.back_since = None
            if m.elapsed() >= m.cfg.link_wait_s:
                m.close(self.reason())
                m.command('gait', 'stand')
                m.go(State.FINISHED, f'giving up, winch braked: the link did not come back '
                                     f'within {m.cfg.link_wait_s:.0f} s')
            return
        if self.back_since is None:
            self.back_since = m.obs.t
            return
        if m.obs.t - self.back_since < m.cfg.link_settle_s:
            return
        self.back_since = None
        resume = self.resume or State.IDLE_MEASURE
        back = f'link back after {m.elapsed():.1f} s'
        if resume in (State.TUG, State.HOLD, State.CHECK, State.CYCLE_DONE):
            if resume == State.TUG:
                m.tug.finish('interrupted')
            at_pose = m.burrow.at_final_pose()
            # A slip during the outage is measured against the anchor's references first (the
            # leg rule only at the burrowed pose: a reset or a stand moves the legs too).
            if m.tug.anchor_slipped(f'during the {m.elapsed():.1f} s outage', legs=at_pose):
                return
            if not at_pose:
                # The legs moved during the outage (an MCU reset, a stand): the anchor that
                # was checked is gone, and the assumed Table II height no longer applies.
                # Burrowed again as any re-burrow: off the dug sand, the tether slack.
                m.burrow.again(f'{back}: the legs left the {m.mode} pose during the outage')
                return
            m.go(State.CHECK, f'{back}: re-checking the {m.mode} anchor before resuming the '
                              f'tug')
        elif resume in WALKING:
            m.go(resume, f'{back}: walking on')
        elif resume == State.BURROW:
            m.cycle.modes.pop()                  # this burrow starts over
            if m.burrow.dug:                     # where its legs dug: as any re-burrow
                m.burrow.again(f'{back}: the burrow was under way')
            else:
                m.burrow.start(m.mode, f'{back}: burrow again')
        elif resume == State.SLACKEN:
            m.go(State.SLACKEN, 'link back: slacken again')
        else:
            m.go(resume, back)
