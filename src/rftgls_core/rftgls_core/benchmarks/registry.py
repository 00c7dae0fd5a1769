"""The one registry of `rftgls bench` figures: sections in run order, and the run itself.

A section is a function returning a list of `timing.Figure`s, named here as
'module:function' (relative to this package, or absolute) and imported only when it runs.
Adding figures is a small edit: write the function next to the code it measures and add one
line to SECTIONS (and to ON_REQUEST if it takes minutes). A figure with `flops` (per unit)
gets `<name>_share_of_peak`, one with `numpy_ref` gets `<name>_vs_numpy`, both computed here
from the same run.

Every run first records the machine and measures its peak (machine.py), whatever sections
are asked for: a figure means little without the CPU it came from and that CPU's limit.
"""
from __future__ import annotations

import importlib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field

from . import machine
from .timing import Figure

SECTIONS: dict[str, str] = {
    'rft': '.engine:engine_figures',
    'capacity': '.capacity:capacity_figures',
    'live': '.live:live_figures',
    'maps': '.maps:map_figures',
    'scaling': '.maps:scaling_figures',
    'sim': '.sim:sim_figures',
    'plan': '.plan:plan_figures',
}
# Sections that run only when named (--only): minutes of work for one figure each.
ON_REQUEST = frozenset({'scaling', 'sim'})


@dataclass
class Run:
    """One run: the machine record and the figures, in order (derived ones after their own)."""

    machine: dict
    figures: list[Figure] = field(default_factory=list)

    def values(self) -> dict[str, float]:
        return {f.name: f.value for f in self.figures}

    def as_json(self) -> dict:
        return {'machine': self.machine, **self.values()}


def section(name: str) -> Callable[[], list[Figure]]:
    """The figure function a SECTIONS entry names."""
    module, _, fn = SECTIONS[name].partition(':')
    return getattr(importlib.import_module(module, __package__), fn)


def derived(figures: list[Figure]) -> list[Figure]:
    """The figures with `<name>_share_of_peak` and `<name>_vs_numpy` after each one that asks.

    share of peak = value x flops / (peak_gflops_<threads>core x 1e9): the share of this
    machine's float64 multiply-add limit, measured in the same run, the figure's arithmetic
    reaches. vs numpy = value / the numpy path's value on the same work.
    """
    by_name = {f.name: f for f in figures}
    out: list[Figure] = []
    for f in figures:
        out.append(f)
        if f.flops:
            peak = by_name.get(f'peak_gflops_{f.threads}core')
            share = f.value * f.flops / (peak.value * 1e9) if peak else math.nan
            out.append(Figure(f'{f.name}_share_of_peak', share, '', budget=(
                '>= 0.5' if f.name == 'rft_pairs_per_s_1core' else ''),
                note=f'{f.flops:g} flops per pair x {f.name} / peak_gflops_{f.threads}core'))
        if f.numpy_ref:
            ref = by_name.get(f.numpy_ref)
            out.append(Figure(f'{f.name}_vs_numpy', f.value / ref.value if ref else math.nan,
                              'x', note=f'{f.name} / {f.numpy_ref}'))
    return out


def run(only: list[str] | None = None, progress: Callable[[str], None] | None = None,
        cpu_target: str = 'native') -> Run:
    """Record the machine, measure its peak, then run the sections asked for (all: None)."""
    unknown = set(only or ()) - set(SECTIONS)
    if unknown:
        raise ValueError(f'unknown bench sections {sorted(unknown)}; known: {list(SECTIONS)}')
    record = machine.machine_record()
    record['cpu_target'] = cpu_target
    if progress:
        progress('machine')
    figures = machine.peak_figures()
    for name in SECTIONS:
        if (only and name not in only) or (not only and name in ON_REQUEST):
            continue
        if progress:
            progress(name)
        figures.extend(section(name)())
    record['loadavg_1min_end'] = round(os.getloadavg()[0], 2) if hasattr(os, 'getloadavg') \
        else math.nan
    return Run(record, derived(figures))
