"""`rftgls bench`: named performance figures (see rftgls_core/bench.py)."""
from __future__ import annotations

import sys

from .. import bench
from ..timing import format_value
from .common import print_json


def add_parser(sub) -> None:
    p = sub.add_parser('bench', help='run the benchmarks and print named figures')
    p.add_argument('--json', action='store_true', help='print JSON {name: value}')
    p.add_argument('--only', nargs='*', choices=sorted(bench.SECTIONS), help='sections to run')
    p.set_defaults(run=run)


def run(args) -> int:
    figures = bench.run_all(args.only, progress=lambda s: print(f'bench: {s} ...',
                                                                  file=sys.stderr))
    if args.json:
        print_json({f.name: f.value for f in figures})
        return 0
    width = max(len(f.name) for f in figures)
    for f in figures:
        line = f'{f.name:<{width}}  {format_value(f):>10} {f.unit:<8}'
        if f.budget:
            line += f'  budget {f.budget}'
        if f.note:
            line += f'  ({f.note})'
        print(line)
    return 0
