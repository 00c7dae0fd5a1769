"""Evidence retry (WAIT_EVIDENCE): an attempt without usable evidence is recorded ``aborted``
with its reason code; the machine then waits, winch braked, for evidence usable for
``evidence_settle_s``, re-checks the same anchor and tugs again as the next cycle. It gives up
(FINISHED) when the evidence is not back within ``evidence_wait_s`` or after more than
``max_aborts`` aborts in one run (docs/design/tug-safety.md, "Retry policy"). Units: s.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from . import evidence
from .states import HoldCause, State

if TYPE_CHECKING:
    from .machine import BehaviorMachine


class EvidenceRetry:
    """WAIT_EVIDENCE, and the abort that leads there."""

    def __init__(self, machine: BehaviorMachine):
        self.m = machine
        self.aborts = 0                              # aborted attempts in this run
        self.usable_since: float | None = None       # s: evidence usable without a break
        self.on_enter = {State.WAIT_EVIDENCE: self._enter_wait_evidence}
        self.on_step = {State.WAIT_EVIDENCE: self._do_wait_evidence}

    def abort(self, v: evidence.Verdict, in_tug: bool) -> None:
        """Record this attempt as aborted (reason code) and wait for evidence (retry policy)."""
        m = self.m
        m.winch = 0.0
        if in_tug:
            m.tug.finish('aborted')
        self.aborts += 1
        m.cycle.outcome = 'aborted'
        m.cycle.cause, m.cycle.reason = HoldCause.EVIDENCE, v.reason
        m.record()
        m.go(State.WAIT_EVIDENCE, f'tug aborted, winch stopped: {v.reason} ({v.detail}); '
                                  f'abort {self.aborts}/{m.cfg.max_aborts}')

    def _enter_wait_evidence(self) -> None:
        self.m.winch = 0.0
        self.usable_since = None

    def _do_wait_evidence(self) -> None:
        m = self.m
        cfg, o = m.cfg, m.obs
        m.winch = 0.0
        if self.aborts > cfg.max_aborts:
            self._give_up(f'{self.aborts} aborted tugs (max_aborts {cfg.max_aborts})')
            return
        if m.evidence().usable:
            if self.usable_since is None:
                self.usable_since = o.t
            if o.t - self.usable_since >= cfg.evidence_settle_s:
                mode = m.mode
                m.new_cycle()
                m.cycle.modes.append(mode)       # the same anchor, burrowed once
                m.go(State.CHECK, f'evidence back: re-checking the {mode} anchor before '
                                  f'tugging again (cycle {m.cycle.index})')
            return
        self.usable_since = None
        if m.elapsed() >= cfg.evidence_wait_s:
            self._give_up(f'no usable capacity estimate within {cfg.evidence_wait_s:.0f} s '
                          f'(status {o.capacity_status})')

    def _give_up(self, why: str) -> None:
        self.m.winch = 0.0
        self.m.command('gait', 'stand')
        self.m.go(State.FINISHED, f'giving up, winch braked: {why}')
