"""Timing helpers of the benchmarks: best-of-N wall time and the named figure it becomes.

A leaf module (imports nothing from the package), so every benchmark section, wherever it
lives (bench.py, maps/bench.py), can use it without importing the package above it.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Figure:
    """One named benchmark figure: value in `unit`, the budget it answers to, how measured."""
    name: str
    value: float
    unit: str
    budget: str = ''
    note: str = ''


def best_time(fn: Callable[[], object], repeats: int = 7, min_total: float = 0.2) -> float:
    """Smallest wall time of one call, s (repeats at least `repeats` times or `min_total` s).

    The minimum is the least disturbed estimate on a shared, noisy machine.
    """
    fn()  # warm up: JIT compile, caches
    times: list[float] = []
    total = 0.0
    while len(times) < repeats or total < min_total:
        t0 = time.perf_counter()
        fn()
        dt = time.perf_counter() - t0
        times.append(dt)
        total += dt
        if len(times) > 1000:
            break
    return min(times)


def format_value(f: Figure) -> str:
    """The figure's value for a table: 3 significant digits, exponent form from 1e4."""
    v = f.value
    if not math.isfinite(v):
        return str(v)
    return f'{v:.3g}' if abs(v) < 1e4 else f'{v:.3e}'
