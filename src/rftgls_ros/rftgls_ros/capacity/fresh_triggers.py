"""Which trigger messages capacity_node answers: the newest, when it has fallen behind.

Every trigger message (by default each tension sample) is applied to the estimator at once:
no input is lost. It is also owed an answer, unless it waited in the subscription's queue
longer than `max_queue_s` (from its DDS source time to its callback). A message that old
means the node is behind: its answer would be built on a sample a newer one already
supersedes, and behavior_node judges every estimate by its sample's age. Answering a backlog
in order makes every answer old (docs/design/stop-budget.md, "Where the age goes when
capacity_node cannot keep up"); skipping the superseded ones makes the node answer the
newest sample as soon as it is free.

A skipped message stays pending: if no fresher trigger comes within `max_queue_s` (it was the
last of a burst), the node answers it then, with its own stamp. `max_queue_s` 0 answers
every trigger in order (the lab's sample-by-sample replay).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class Pending:
    """A skipped trigger still owed an answer: its header stamp (None: no header) and its
    DDS source time, ns (system clock)."""

    stamp: Any
    source_ns: int


@dataclass
class FreshTriggers:
    """max_queue_s: longest wait in the queue, s, after which a trigger is applied but not
    answered on its own (0: every trigger is answered). skipped: how many were skipped."""

    max_queue_s: float
    pending: Pending | None = None
    skipped: int = 0

    def __post_init__(self) -> None:
        if not self.max_queue_s >= 0.0:
            raise ValueError(f'max_queue_s must be >= 0, got {self.max_queue_s!r}')

    def arrived(self, queued_s: float, stamp: Any, source_ns: int) -> bool:
        """A trigger message whose inputs are applied; True: answer it now. False: it is
        pending (the node is behind); a later trigger or `take_pending` answers it."""
        if self.max_queue_s > 0.0 and queued_s > self.max_queue_s:
            self.pending = Pending(stamp, source_ns)
            self.skipped += 1
            return False
        self.pending = None
        return True

    def take_pending(self) -> Pending | None:
        """The skipped trigger no newer one has answered (then nothing is pending)."""
        p, self.pending = self.pending, None
        return p
