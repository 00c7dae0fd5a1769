"""`rftgls plan burrow`: the cheapest burrow whose lower-bound capacity holds the need
(rftgls_core/planning; docs/design/burrow-planner.md), and `rftgls plan build-map`: the gait
map it answers from onboard.

Exit status: 0 when a gait covers the need, 1 when none does (status `unsupported`, reason
`need_not_covered`: an answer, with no gait offered), 2 on bad input (the CLI contract)."""
from __future__ import annotations

import math
import sys
from pathlib import Path

from rftgls_conventions import G
from rftgls_conventions.safe_write import output_file, output_folder, write_text

from ..quantities import CONFIDENCE, MASS_KG, NEED_FORCE_N, TETHER_PHI_DEG, WORKERS
from .common import add_medium_args, medium_from_args, print_json

EXIT_NOT_COVERED = 1


def add_parser(sub) -> None:
    p = sub.add_parser('plan', help='plan a burrow: the cheapest gait whose lower bound holds')
    sub2 = p.add_subparsers(dest='what', required=True)
    b = sub2.add_parser('burrow', help='the cheapest burrow gait whose lower-bound capacity '
                        'covers a need', description='Searches the burrow gaits the robot can '
                        'run (retracting and final leg angles, slew speed), predicts each '
                        'burrowed pose with the whole-robot simulation over the medium and '
                        'servo spread, and the capacity there for every tether angle; prints '
                        'the Pareto front (lower bound against electrical energy), the chosen '
                        'gait and the paper\'s DH, DL and SH. Exit 0: a gait covers the need; '
                        '1: none does; 2: bad input.')
    _common(b)
    b.add_argument('--need-N', dest='need_n', type=NEED_FORCE_N.arg, required=True,
                   help='the pull the anchor must hold, N (400 g sled: 1.96)')
    b.add_argument('--confidence', type=CONFIDENCE.arg, default=0.95,
                   help='one-sided confidence of the lower bound (default 0.95)')
    b.add_argument('--map', help='a gait map (HDF5, `rftgls plan build-map`); default: the '
                   'robot\'s shipped one when it answers for these inputs')
    b.add_argument('--live', action='store_true', help='simulate now, whatever maps exist')
    b.add_argument('--out', help='folder for plan.json and front.png')
    b.set_defaults(run=run_burrow)
    m = sub2.add_parser('build-map', help='precompute the gait space into a gait map (HDF5)')
    _common(m)
    m.add_argument('--out', required=True, help='the map file (.h5)')
    m.add_argument('--scheduler', help='Dask scheduler address tcp://HOST:PORT (instead of '
                   'local workers)')
    m.set_defaults(run=run_build)


def _common(p) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument('--robot', choices=('minirquad', 'prototype'), default=None,
                   help='a preset robot (default minirquad)')
    g.add_argument('--anchor', help='a described robot: its description YAML')
    p.add_argument('--phi', required=True, type=_phis, metavar='DEG[,DEG...]',
                   help='tether angles the tug passes through, deg')
    p.add_argument('--pull', choices=('backward', 'forward'), default='backward',
                   help='C-leg orientation (MiniRQuad tugs backward)')
    p.add_argument('--sled', type=MASS_KG.arg, default=None, metavar='KG',
                   help='the sled tied to p while the robot burrows (0: no rope); default: '
                        'the sled the need drags, need / (0.5 g)')
    p.add_argument('--workers', type=WORKERS, default=None,
                   help='processes for the simulations (default: all cores)')
    p.add_argument('--json', action='store_true', help='print the result as JSON')
    add_medium_args(p)


def _phis(text: str) -> tuple[float, ...]:
    import argparse
    parts = [t.strip() for t in text.split(',')]
    if not parts or any(not t for t in parts):
        raise argparse.ArgumentTypeError(f'give angles separated by commas, got {text!r}')
    vals = tuple(TETHER_PHI_DEG.arg(t) for t in parts)
    if len(set(vals)) != len(vals):
        raise argparse.ArgumentTypeError(f'an angle is given twice: {text!r}')
    return vals


def inputs_from_args(args, need_n: float | None):
    """PlanInputs of the command line (the medium's covariance from its calibration file, else
    assumed)."""
    from ..multibody.sled import SLED_MU
    from ..planning.predict import PlanInputs
    from ..planning.spread import Spread
    from ..rft.media import medium_covariance
    if args.anchor:
        from ..description import load_description
        args.default_medium = load_description(args.anchor).medium
        robot, anchor = args.anchor, True
    else:
        robot, anchor = args.robot or 'minirquad', False
        args.default_medium = 'glass_beads' if robot == 'prototype' else 'm90_sand'
    medium = medium_from_args(args)
    cov, source = medium_covariance(args.medium, medium.xi_n)
    if args.sled is not None:
        sled = args.sled
    elif need_n is not None:
        # the sled the need drags, to 10 g (a sled is weighed to grams, its friction assumed)
        sled = round(need_n / (SLED_MU * G), 2)
    else:
        raise ValueError('give --sled KG (0: no rope): a gait map is built for one sled')
    return PlanInputs(robot, medium, Spread.of(cov, source),
                      tuple(math.radians(p) for p in args.phi), sled_kg=float(sled),
                      pull=args.pull, anchor=anchor)


def run_burrow(args) -> int:
    from ..planning.planner import plan_burrow
    if args.out:
        output_folder(args.out, '--out')
    if args.live and args.map:
        raise ValueError('give --map or --live, not both')
    inputs = inputs_from_args(args, args.need_n)
    plan = plan_burrow(inputs, args.need_n, args.confidence, map_path=args.map,
                       live=args.live, workers=args.workers,
                       progress=not args.json and sys.stderr.isatty())
    d = plan.to_json()
    d['robot'] = inputs.multibody().name
    d['medium'] = inputs.medium.name
    d['sled_kg'] = inputs.sled_kg
    d['sled_source'] = 'given (--sled)' if args.sled is not None else 'from the need'
    d['spread'] = inputs.spread.describe()
    d['elapsed_s'] = plan.source['elapsed_s']
    if args.out:
        import json

        from ..charts.plan_front import plot_front
        out = Path(args.out)
        write_text(out / 'plan.json', json.dumps(d, indent=2, allow_nan=False) + '\n')
        plot_front(plan, out / 'front.png', title=f'{d["robot"]} in {d["medium"]}')
        d['files'] = [str(out / 'plan.json'), str(out / 'front.png')]
    if args.json:
        print_json(d)
    else:
        _print(d)
    return 0 if plan.ok else EXIT_NOT_COVERED


def _print(d: dict) -> None:
    def line(a: dict) -> str:
        pose = a['pose']
        where = (f"h {pose['h_m'] * 1e3:.1f} mm, theta_b {pose['theta_b_deg']:.1f} deg"
                 if pose else 'no pose')
        lb = 'none' if a['lower_bound_N'] is None else f"{a['lower_bound_N']:.2f} N"
        e = 'n/a' if a['energy_elec_J'] is None else f"{a['energy_elec_J']:.2f} J"
        return (f"retract {a['retract_deg']} final {a['final_deg']} deg: {where}; lower bound "
                f"{lb}, energy {e} ({a['status']})")
    print(f"plan for {d['need_N']:.3g} N at {d['confidence']:.0%}: {d['status']}"
          + ('' if d['chosen'] else f" ({d['reason']})"))
    if d['chosen']:
        print('  chosen: ' + line(d['chosen']))
    print(f"  front: {len(d['front'])} gaits of {d['candidates']} candidates "
          f"({d['source']['kind']})")
    for name, a in d['modes'].items():
        print(f'  {name} ({a["place"]}): ' + line(a))
    print(f"  {d['elapsed_s']:.2f} s")


def run_build(args) -> int:
    from ..planning.gait_map import build_gait_map, save
    from ..planning.planner import gait_space
    out = output_file(args.out, '--out')
    inputs = inputs_from_args(args, None)
    gmap = build_gait_map(inputs, gait_space(), workers=args.workers, scheduler=args.scheduler,
                          progress=sys.stderr.isatty(),
                          command='rftgls ' + ' '.join(sys.argv[1:]))
    save(out, gmap)
    n_ok = sum(s[0] in ('ok', 'assumed') for s in gmap.arrays['status'])
    print(f'wrote {out}: {len(gmap.arrays["gaits"])} gaits ({n_ok} with a pose), inputs '
          f'{gmap.inputs_sha256[:12]}...')
    return 0
