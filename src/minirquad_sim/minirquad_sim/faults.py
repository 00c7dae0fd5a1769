"""Fault injection on the simulated MCU's output stream.

Each outgoing frame may be preceded by junk bytes, dropped, or have 1-3 bits flipped on the
wire (inside the frame, not the delimiters, so the damage is what a noisy line does to a
frame rather than a framing change), and is released after a latency. Disconnects and
resets are scheduled by time and handled by the loop in ``main.py``. ``FaultControl`` lets a
test switch the per-frame faults on and off while the simulator runs (a fault that starts
mid-tug), through a small JSON file.
"""
from __future__ import annotations

import os
import random
from collections import Counter
from dataclasses import dataclass, replace

from rftgls_conventions.safe_read import parse_json, read_text


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


LIVE_FIELDS = ('garbage_rate', 'drop_rate', 'corrupt_rate', 'latency_ms', 'jitter_ms')


class FaultControl:
    """Per-frame faults switched while running: the file holds a JSON object of LIVE_FIELDS
    (a missing field is 0, ``{}`` switches them all off). The file is looked at every
    ``period`` s of the simulator's clock and applied when its modification time changes;
    a file that does not parse keeps the faults as they were and says why on stderr."""

    def __init__(self, path: str, period: float = 0.02):
        self.path, self.period = path, period
        self._next = 0.0
        self._mtime: int | None = None

    def poll(self, now: float, config: FaultConfig) -> FaultConfig | None:
        """The new config when the file changed since the last look, else None."""
        if now < self._next:
            return None
        self._next = now + self.period
        try:
            mtime = os.stat(self.path).st_mtime_ns
        except OSError:
            return None
        if mtime == self._mtime:
            return None
        self._mtime = mtime
        spec = parse_json(read_text(self.path, 'params', 'fault control'), self.path)
        if not isinstance(spec, dict) or not set(spec) <= set(LIVE_FIELDS) or not all(
                isinstance(v, (int, float)) and 0 <= v for v in spec.values()):
            raise ValueError(f'{self.path}: a JSON object of {", ".join(LIVE_FIELDS)} '
                             f'(numbers >= 0) expected, got {spec!r}')
        return replace(config, **{k: float(spec.get(k, 0.0)) for k in LIVE_FIELDS})
