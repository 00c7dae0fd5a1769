"""`rftgls plot`: limit surface, limit curve, load ray, capacity and slip twist of one pose."""
from __future__ import annotations

import math

from ..charts.limit_surface import plot_limit_surface
from ..surfaces.registry import METHOD_NAMES
from .capacity import add_state_args, model_from_args, state_from_args


def add_parser(sub) -> None:
    p = sub.add_parser('plot', help='plot the limit surface and capacity of one pose (PNG)')
    add_state_args(p)
    p.add_argument('--method', choices=list(METHOD_NAMES), default='twist-mesh')
    p.add_argument('--twists', type=int, default=None)
    p.add_argument('--out', required=True, help='PNG file to write')
    p.set_defaults(run=run)


def run(args) -> int:
    model = model_from_args(args)
    info = plot_limit_surface(model, state_from_args(args), args.pull, math.radians(args.phi),
                              args.out)
    print(f'wrote {args.out}: capacity {info["capacity_N"]} N, status {info["status"]}')
    return 0
