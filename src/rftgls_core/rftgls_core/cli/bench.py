"""`rftgls bench`: named performance figures (rftgls_core/benchmarks), the machine they came
from, and docs/performance.md's table (`--markdown`).

`--cpu x86-64-v3` runs the same benchmarks as a Zen 3 class CPU (AVX2 + FMA, no AVX-512) would
compile and dispatch them: the command starts itself again with numba's target, numpy's SIMD
dispatch and OpenBLAS's kernels limited (benchmarks/machine.py, CPU_TARGETS); the clock and
caches stay this machine's.
"""
from __future__ import annotations

import os
import shlex
import subprocess
import sys

from ..benchmarks import registry
from ..benchmarks.machine import CPU_TARGETS
from ..benchmarks.timing import format_value
from .common import print_json

_TARGET_ENV = 'RFTGLS_BENCH_CPU_TARGET'


def add_parser(sub) -> None:
    p = sub.add_parser('bench', help='run the benchmarks and print named figures')
    p.add_argument('--json', action='store_true',
                   help='print JSON {"machine": {...}, name: value, ...}')
    p.add_argument('--only', nargs='*', choices=sorted(registry.SECTIONS),
                   help='sections to run (the machine record and peak always run)')
    p.add_argument('--cpu', choices=sorted(CPU_TARGETS),
                   help='compile and dispatch as this x86-64 class (re-runs the command)')
    p.add_argument('--markdown', metavar='FILE',
                   help="write the run's table between the markers of FILE "
                        '(docs/performance.md)')
    p.set_defaults(run=run)


def _argv(args) -> list[str]:
    """The command's arguments (after `rftgls`), as given."""
    parts = ['bench']
    if args.cpu:
        parts += ['--cpu', args.cpu]
    if args.only:
        parts += ['--only', *args.only]
    if args.markdown:
        parts += ['--markdown', args.markdown]
    if args.json:
        parts.append('--json')
    return parts


def run(args) -> int:
    if args.cpu and os.environ.get(_TARGET_ENV) != args.cpu:
        # numba and numpy read their targets at import: only a fresh process can change them.
        env = {**os.environ, **CPU_TARGETS[args.cpu], _TARGET_ENV: args.cpu}
        return subprocess.call([sys.executable, '-m', 'rftgls_core.cli.main', *_argv(args)],
                               env=env)
    result = registry.run(args.only, progress=lambda s: print(f'bench: {s} ...',
                                                              file=sys.stderr),
                          cpu_target=args.cpu or 'native')
    if args.markdown:
        from ..benchmarks.report import write_markdown
        write_markdown(args.markdown, result,
                       shlex.join(['rftgls', *(a for a in _argv(args) if a != '--json')]))
    if args.json:
        print_json(result.as_json())
        return 0
    from ..benchmarks.machine import describe
    print(describe(result.machine))
    width = max(len(f.name) for f in result.figures)
    for f in result.figures:
        line = f'{f.name:<{width}}  {format_value(f):>10} {f.unit:<8}'
        if f.budget:
            line += f'  budget {f.budget}'
        if f.note:
            line += f'  ({f.note})'
        print(line)
    return 0
