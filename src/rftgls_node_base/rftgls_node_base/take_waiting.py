"""Take the messages waiting in a subscription's queue now, inside the running callback, instead
of when the executor gets to them.

Why: rclpy's executor (Jazzy, ``Executor._wait_for_ready_callbacks``) hands out the ready
timers of a wait before its ready subscriptions. A timer that judges how old the last message
is can therefore run while a newer message already waits in the queue, and judge the old one.
behavior_node's evidence check is such a timer (docs/design/stop-budget.md): it takes what
waits first, then judges.

Only from a callback of the executor that spins the subscription's node, in a single-threaded
executor: the executor's own take for a message taken here finds the queue empty, and rclpy
then runs no callback (``Executor._take_subscription``: ``take_message`` answers None).
"""
from __future__ import annotations

MAX_TAKEN = 100   # more waiting than a queue of this depth holds means something else is wrong


def take_waiting(subscription, limit: int = MAX_TAKEN) -> list:
    """The messages waiting in `subscription`'s queue, oldest first (at most `limit`); the
    queue is empty afterwards unless more were waiting."""
    taken: list = []
    with subscription.handle:
        while len(taken) < limit:
            # the same take rclpy's executor makes (Executor._take_subscription)
            got = subscription.handle.take_message(subscription.msg_type, subscription.raw)
            if got is None:
                break
            taken.append(got[0])
    return taken
