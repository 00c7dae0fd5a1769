"""Mapping MCU time into the host clock, biased so that a sample never looks fresher than it is.

Let theta = host wall time - MCU time (s), the unknown clock offset. Two kinds of evidence
bound it (docs/design/serial-time.md):

* Every frame the host receives at host time ``h`` and stamped ``m`` by the MCU was sent
  before it arrived: theta <= h - m (an upper bound; the gap is the one-way link delay).
* Every ack of a host frame sent at host time ``h0``, stamped ``m1`` by the MCU when it
  answered, was written after the host frame left: theta >= h0 - m1 (a lower bound; the gap
  is the host-to-MCU delay plus the MCU's turnaround).

Stamps use the LOWER bound: stamp = m + theta_low <= m + theta, the true host time of the
sample. Whatever delay the MCU-to-host direction adds (a slow link, a stalled host) shows in
the stamp; the error is only ever towards "older", by at most the host-to-MCU delay. Without
a lower bound there is no stamp at all (the caller withholds the sample).

Both bounds come from a sliding window and widen with the allowed crystal drift, so an old
bound never outlives what it can vouch for.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

#: The MCU stamps whole milliseconds (truncated), so its true time lies in [m, m + 1 ms).
MCU_RESOLUTION_S = 1e-3


@dataclass
class _WindowExtreme:
    """Sliding-window maximum of ``key`` values, each kept ``window`` seconds from its time."""

    window: float
    _q: deque = field(default_factory=deque)   # (t, key), keys strictly decreasing

    def add(self, t: float, key: float) -> None:
        while self._q and self._q[-1][1] <= key:
            self._q.pop()
        self._q.append((t, key))

    def best(self, now: float) -> float | None:
        while self._q and now - self._q[0][0] > self.window:
            self._q.popleft()
        return self._q[0][1] if self._q else None

    def clear(self) -> None:
        self._q.clear()


class TimeSync:
    """Bounds on theta = host - MCU time (s) from arrivals and round trips.

    drift: s/s the offset may move (crystal tolerance); window: s a bound is kept.
    All times are host wall-clock seconds (the ROS clock) and MCU seconds (unwrapped).
    """

    def __init__(self, drift: float = 2e-4, window: float = 10.0):
        self.drift = drift
        # A bound b taken at time t is worth b - drift*(now - t) (lower) at ``now``: keeping
        # the key b + drift*t makes the best bound's index independent of ``now``.
        self._low = _WindowExtreme(window)
        self._high = _WindowExtreme(window)     # holds -(b - drift*t): a minimum
        self.round_trips = 0

    def reset(self) -> None:
        """A new MCU time base (reset, reconnect): nothing known about the offset."""
        self._low.clear()
        self._high.clear()

    def add_arrival(self, host_s: float, mcu_s: float) -> None:
        """A frame stamped ``mcu_s`` was read at ``host_s``: theta <= host_s - mcu_s."""
        self._high.add(host_s, -((host_s - mcu_s) - self.drift * host_s))

    def add_round_trip(self, sent_host_s: float, reply_mcu_s: float) -> None:
        """A host frame written at ``sent_host_s`` was answered at MCU time ``reply_mcu_s``
        (the truncated ms stamp): theta > sent_host_s - reply_mcu_s - 1 ms."""
        b = sent_host_s - reply_mcu_s - MCU_RESOLUTION_S
        self._low.add(sent_host_s, b + self.drift * sent_host_s)
        self.round_trips += 1

    def lower(self, now: float) -> float | None:
        k = self._low.best(now)
        return None if k is None else k - self.drift * now

    def upper(self, now: float) -> float | None:
        k = self._high.best(now)
        return None if k is None else -k + self.drift * now

    def to_host(self, mcu_s: float, now: float) -> float | None:
        """Host time of the MCU instant ``mcu_s``, never later than the truth; None when no
        round trip vouches for the offset. Never later than ``now`` either."""
        low = self.lower(now)
        if low is None:
            return None
        return min(mcu_s + low, now)

    def uncertainty(self, now: float) -> float | None:
        """Width of the offset interval, s: how much older than the truth a stamp may be."""
        low, high = self.lower(now), self.upper(now)
        return None if low is None or high is None else max(0.0, high - low)
