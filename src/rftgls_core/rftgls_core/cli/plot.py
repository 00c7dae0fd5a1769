"""`rftgls plot`: limit surface, limit curve, load ray, capacity and slip twist of one pose."""
from __future__ import annotations

import math

from ..charts.figure_io import figure_path
from ..charts.limit_surface import plot_limit_surface
from ..predictor import build_predictor
from ..predictor.live import RobotPredictor
from ..surfaces.registry import METHOD_NAMES
from .capacity import CLI_NAMES, add_body_args, add_state_args, spec_from_args, state_from_args
from .common import twist_count


def add_parser(sub) -> None:
    p = sub.add_parser('plot', help='plot the limit surface and capacity of one pose (PNG)')
    add_state_args(p)
    add_body_args(p)
    p.add_argument('--against-yaw', action='store_true',
                   help='plot capacity against the tether yaw (-90..90 deg) and the limit '
                        'curve in the pull plane (implied by --mesh); numbers go to .json')
    p.add_argument('--method', choices=list(METHOD_NAMES), default='twist-mesh')
    p.add_argument('--twists', type=twist_count, default=None)
    p.add_argument('--out', required=True, help='PNG file to write')
    p.set_defaults(run=run)


def run(args) -> int:
    figure_path(args.out)     # what --out means is checked before any work
    if (args.anchor is not None or args.mesh is not None or args.against_yaw or args.yaw != 0.0
            or args.space != 'auto'):
        return run_posed(args)
    predictor = build_predictor(spec_from_args(args), CLI_NAMES)
    assert isinstance(predictor, RobotPredictor)     # --method is a live method here
    info = plot_limit_surface(predictor, state_from_args(args), args.pull, math.radians(args.phi),
                              args.out)
    print(f'wrote {args.out}: capacity {info["capacity_N"]} N, status {info["status"]}')
    return 0


def run_posed(args) -> int:
    """Capacity of a rigid body or a robot against yaw and tether angle (docs/design/six-d.md)."""
    import json
    from pathlib import Path

    from rftgls_conventions.safe_write import write_text

    from ..charts.posed_capacity import plot_posed_capacity
    from ..posed import PosedAnchorSolver
    from ..predictor.spec import DEFAULT_ROBOT, ROBOT_MEDIUM
    from .capacity import posed_from_args
    from .common import medium_from_args
    args.default_medium = (ROBOT_MEDIUM[args.robot or DEFAULT_ROBOT] if args.mesh is None
                           else 'glass_beads')
    posed = posed_from_args(args)
    args.default_medium = getattr(args, 'description_medium', args.default_medium)
    solver = PosedAnchorSolver(medium_from_args(args), model=args.model, method=args.method,
                               n_twists=args.twists, space=args.space)
    data = plot_posed_capacity(solver, posed, math.radians(args.phi), math.radians(args.yaw),
                               args.out)
    write_text(Path(args.out).with_suffix('.json'), json.dumps(data, indent=2))
    caps = [c for c in data['by_yaw']['capacity_N'] if c is not None]
    span = f'{min(caps):.3g}..{max(caps):.3g} N' if caps else 'no value'
    print(f'wrote {args.out} (and .json): capacity over yaw {span}')
    return 0
