"""Fault injection on the simulated MCU's output stream.

Each outgoing frame may be preceded by junk bytes, dropped, or have 1-3 bits flipped on the
wire (inside the frame, not the delimiters, so the damage is what a noisy line does to a
frame rather than a framing change), and is released after a latency. Disconnects and
resets are scheduled by time and handled by the loop in ``main.py``.
"""
from __future__ import annotations

import random
from collections import Counter
from dataclasses import dataclass


@dataclass
class FaultConfig:
    """Rates are probabilities per outgoing frame; times are seconds since start."""

    garbage_rate: float = 0.0
    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    latency_ms: float = 0.0
    jitter_ms: float = 0.0
    disconnect_at: float | None = None
    disconnect_for: float = 1.0
    reset_at: float | None = None
    seed: int = 1


class FaultInjector:
    def __init__(self, config: FaultConfig):
        self.config = config
        self.rng = random.Random(config.seed)
        self.counts: Counter[str] = Counter()

    def outgoing(self, data: bytes, now: float) -> tuple[float, bytes, str | None]:
        """(release time, bytes to write, fault applied to the frame or None)."""
        c, rng = self.config, self.rng
        fault = None
        prefix = b''
        if c.garbage_rate and rng.random() < c.garbage_rate:
            n = rng.randint(1, 40)
            prefix = bytes(rng.randrange(256) for _ in range(n))
            self.counts['garbage'] += 1
        if c.drop_rate and rng.random() < c.drop_rate:
            data = b''
            fault = 'drop'
        elif c.corrupt_rate and rng.random() < c.corrupt_rate and len(data) > 3:
            buf = bytearray(data)
            spots = rng.sample([(p, b) for p in range(1, len(buf) - 1) for b in range(8)],
                               rng.randint(1, 3))
            for pos, bit in spots:
                buf[pos] ^= 1 << bit
            data = bytes(buf)
            fault = 'corrupt'
        if fault:
            self.counts[fault] += 1
        delay = c.latency_ms + (rng.uniform(0.0, c.jitter_ms) if c.jitter_ms else 0.0)
        return now + delay * 1e-3, prefix + data, fault
