"""Timing helpers of the benchmarks: best-of-N wall time and the named figure it becomes.

A leaf module (imports nothing from the package), so every benchmark section can use it
without importing the registry above it.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TypeVar

K = TypeVar('K')


@dataclass(frozen=True)
class Figure:
    """One named benchmark figure: value in `unit`, the budget it answers to, how measured.

    flops: floating-point operations per unit of `value` (per facet-twist pair for pairs/s);
    with it the registry adds `<name>_share_of_peak` against the run's measured peak on
    `threads` threads. numpy_ref: the name of the same work on the numpy reference path;
    with it the registry adds `<name>_vs_numpy` (this figure / that one, both rates).
    """
    name: str
    value: float
    unit: str
    budget: str = ''
    note: str = ''
    flops: float = 0.0
    threads: int = 1
    numpy_ref: str = ''


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


def best_times_alternating(fns: Mapping[K, Callable[[], object]], rounds: int = 5
                           ) -> dict[K, float]:
    """Smallest wall time of each function, s, called in turn `rounds` times (A B A B ...):
    load that comes and goes on a shared machine then hits all of them alike, and their
    ratio means something."""
    for fn in fns.values():
        fn()   # warm up
    best = {k: math.inf for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return best


def format_value(f: Figure) -> str:
    """The figure's value for a table: 3 significant digits, exponent form from 1e4."""
    v = f.value
    if not math.isfinite(v):
        return str(v)
    return f'{v:.3g}' if abs(v) < 1e4 else f'{v:.3e}'
