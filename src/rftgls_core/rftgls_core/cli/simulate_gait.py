"""`rftgls simulate burrow` and `rftgls simulate walk`: a whole robot running a gait on sand
(rftgls_core/multibody; docs/design/walk-burrow-physics.md)."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from rftgls_conventions.safe_write import output_folder, write_text

from ..multibody.gaits import TABLE_II_BURROWS as TABLE_II
from ..quantities import (
    ANGLE_DEG,
    GAIT_DUTY,
    GAIT_PERIOD_S,
    LEG_SPEED_DEG_S,
    MASS_KG,
    SIM_DURATION_S,
    SIM_STEP_S,
    STALL_TORQUE_NM,
    bounded_int,
)
from .common import add_medium_args, medium_from_args, print_json


def add_parsers(sub) -> None:
    b = sub.add_parser('burrow', help='a robot burrowing its legs (retracting, then final pose)',
                       description='Simulates a burrow: the robot is put down standing, settles, '
                       'moves its legs to the retracting and then the final pose and holds until '
                       'the window ends. Prints the pose reached, stalls and energies.')
    _robot_args(b)
    b.add_argument('--mode', choices=sorted(TABLE_II), help='a burrow of the paper\'s Table II')
    b.add_argument('--retract', nargs=2, type=ANGLE_DEG.arg, metavar=('DEG', 'DEG'),
                   help='retracting pose, one angle per degree of freedom (deg)')
    b.add_argument('--final', nargs=2, type=ANGLE_DEG.arg, metavar=('DEG', 'DEG'),
                   help='final pose (deg)')
    b.add_argument('--stand', nargs=2, type=ANGLE_DEG.arg, default=(0.0, 0.0),
                   metavar=('DEG', 'DEG'), help='standing pose the burrow starts from (deg)')
    b.add_argument('--speed', type=LEG_SPEED_DEG_S.arg, default=None,
                   help='leg speed of the moves, deg/s (default: 57.3 deg/s, i.e. 1 rad/s, an '
                        'assumption: the paper gives no timing)')
    b.add_argument('--duration', type=SIM_DURATION_S.arg, default=8.0, help='window, s (paper: 8)')
    b.set_defaults(run=run_burrow)
    w = sub.add_parser('walk', help='a robot walking with MiniRHex\'s Buehler clock',
                       description='Simulates a walk: one Buehler clock per leg (MiniRHex\'s '
                       'walk: period 2 s, duty 0.42, sweep 40 deg), amble phases. Prints the '
                       'distance, speed, energy and mean height.')
    _robot_args(w)
    w.add_argument('--duration', type=SIM_DURATION_S.arg, default=8.0, help='s')
    w.add_argument('--period', type=GAIT_PERIOD_S.arg, default=2.0, help='clock period, s')
    w.add_argument('--duty', type=GAIT_DUTY.arg, default=0.42, help='stance fraction')
    w.add_argument('--sweep', type=ANGLE_DEG.arg, default=40.0, help='stance sweep, deg')
    w.add_argument('--down', type=ANGLE_DEG.arg, default=-20.0,
                   help='stance centre as theta_L, deg (MiniRHex\'s 20 deg, turned forward)')
    w.add_argument('--direction', type=int, choices=(1, -1), default=1)
    w.set_defaults(run=run_walk)
    s = sub.add_parser('sensitivity', help='each prediction compared with the paper, with one '
                       'input changed at a time (JSON and a chart)')
    s.add_argument('--out', required=True, help='folder for sensitivity.json and .png')
    s.add_argument('--no-walk', action='store_true', help='burrows only (faster)')
    s.add_argument('--modes', default='DH,DL,SH',
                   help='burrows to run, comma-separated (default DH,DL,SH)')
    s.add_argument('--sled', type=MASS_KG.arg, default=None, metavar='KG',
                   help='tie every burrow to a sled of this mass (as simulate burrow --sled)')
    s.set_defaults(run=run_sensitivity)


def _robot_args(p) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument('--robot', choices=('minirquad', 'prototype'), default=None,
                   help='a preset robot (default minirquad)')
    g.add_argument('--anchor', help='a described robot: its description YAML')
    p.add_argument('--pull', choices=('backward', 'forward'), default='backward',
                   help='C-leg orientation (types.Pull; MiniRQuad walks and tugs backward)')
    p.add_argument('--leg-segments', type=bounded_int(4, 400, 'leg segments'), default=None,
                   help='C-leg mesh segments along the arc (presets; default 24)')
    p.add_argument('--stall-torque', type=STALL_TORQUE_NM.arg, default=None,
                   help='servo stall torque, N m (default: the XL330-M077-T datasheet, 0.215)')
    p.add_argument('--sled', type=MASS_KG.arg, default=None, metavar='KG',
                   help='tie p to a sled of this mass lying 0.5 m behind, the rope just taut '
                        'at the start (multibody/sled.py; default: no rope)')
    p.add_argument('--dt', type=SIM_STEP_S.arg, default=0.02, help='largest time step, s')
    p.add_argument('--json', action='store_true', help='print the summary as JSON')
    p.add_argument('--out', help='folder for trajectory.csv, summary.json and a plot')
    add_medium_args(p)


def build(args):
    """(robot, medium, simulator) of the command line; the output folder is checked first."""
    if args.out:
        output_folder(args.out, '--out')
    from ..multibody.robot import from_preset
    from ..multibody.servo import XL330_M077_5V
    from ..multibody.simulate import SimOptions, Simulator
    from ..robots.presets import LEG_ARC_SEGMENTS, get_robot
    if args.anchor:
        from ..description import load_description
        from ..multibody.described import from_description
        if args.leg_segments is not None:
            raise ValueError('--leg-segments applies to the preset robots; a described robot '
                             'brings its meshes')
        desc = load_description(args.anchor)
        robot = from_description(desc, args.pull)
        args.default_medium = desc.medium
    else:
        name = args.robot or 'minirquad'
        n = LEG_ARC_SEGMENTS if args.leg_segments is None else args.leg_segments
        if not 4 <= n <= 400:
            raise ValueError(f'--leg-segments must be in 4..400, got {n}')
        robot = from_preset(get_robot(name, n), args.pull)
        args.default_medium = 'glass_beads' if name == 'prototype' else 'm90_sand'
    servo = XL330_M077_5V
    if args.stall_torque is not None:
        if not args.stall_torque > 0.0:
            raise ValueError(f'--stall-torque must be > 0 N m, got {args.stall_torque}')
        servo = servo.scaled(args.stall_torque / servo.stall_torque)
    if not (args.dt > 0.0 and args.dt <= args.duration):
        raise ValueError(f'--dt must be in (0, --duration], got {args.dt}')
    medium = medium_from_args(args)
    sled = None
    if args.sled is not None:
        from ..multibody.sled import Sled
        sled = Sled(args.sled)
    return robot, Simulator(robot, medium, servo, SimOptions(dt=args.dt), model=args.model,
                            sled=sled)


def run_burrow(args) -> int:
    from ..multibody.gaits import DEFAULT_BURROW_SPEED, BurrowGait
    from ..multibody.validate import check_gait
    robot, sim = build(args)
    if args.mode and (args.retract or args.final):
        raise ValueError('give --mode or --retract/--final, not both')
    if args.mode:
        retract, final = TABLE_II[args.mode]
    elif args.retract and args.final:
        retract, final = args.retract, args.final
    else:
        raise ValueError('give --mode DH|DL|SH or both --retract DEG DEG and --final DEG DEG')
    n = len(robot.dof_names)
    if n != 2:
        raise ValueError(f'{robot.name} has {n} degrees of freedom ({", ".join(robot.dof_names)});'
                         ' --stand/--retract/--final give two')
    speed = DEFAULT_BURROW_SPEED if args.speed is None else math.radians(args.speed)
    gait = BurrowGait(robot, tuple(math.radians(a) for a in args.stand),
                      tuple(math.radians(a) for a in retract),
                      tuple(math.radians(a) for a in final), speed=speed,
                      duration=args.duration)
    check_gait(robot, gait)
    return _finish(args, sim, gait, f'burrow {args.mode or "custom"}')


def run_walk(args) -> int:
    from ..multibody.gaits import WalkGait
    from ..multibody.validate import check_gait
    robot, sim = build(args)
    gait = WalkGait(robot, duration=args.duration, period=args.period, duty=args.duty,
                    sweep=math.radians(args.sweep), down=math.radians(args.down),
                    direction=args.direction)
    check_gait(robot, gait)
    return _finish(args, sim, gait, 'walk')


def _finish(args, sim, gait, what: str) -> int:
    from tqdm import tqdm
    bar = tqdm(total=round(gait.duration, 3), unit='s', file=sys.stderr, desc=what, leave=False,
               disable=args.json or not sys.stderr.isatty())
    res = sim.run(gait, progress=lambda t: bar.update(round(t, 3) - bar.n))
    bar.close()
    summary = res.summary()
    if args.out:
        out = Path(args.out)
        res.write_csv(out / 'trajectory.csv')
        write_text(out / 'summary.json', json.dumps(_jsonable(summary), indent=2) + '\n')
        from ..charts.multibody import plot_run
        plot_run(sim.robot, res, out / 'run.png', title=f'{sim.robot.name}: {what}')
        summary['files'] = [str(out / f) for f in ('trajectory.csv', 'summary.json', 'run.png')]
    if args.json:
        print_json(_jsonable(summary))
    else:
        _print(summary)
    return 0    # a run without a value is an answer too: its status says so (as capacity)


def _jsonable(d):
    if isinstance(d, dict):
        return {k: _jsonable(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_jsonable(v) for v in d]
    if hasattr(d, 'item'):
        return d.item()
    if isinstance(d, float) and not math.isfinite(d):
        return None
    return d


def _print(s: dict) -> None:
    print(f"{s['robot']}: status {s['status']}" + (f" ({s['reason']}: {s['detail']})"
                                                   if s['status'] not in ('ok', 'assumed')
                                                   else ''))
    if s.get('h_m') is None:
        return
    dofs = ', '.join(f'{k[:-4]} {v:.1f} deg' for k, v in s.items()
                     if k.endswith('_deg') and k != 'theta_b_deg')
    print(f"  final: h {s['h_m'] * 1e3:.1f} mm, theta_b {s['theta_b_deg']:.1f} deg, {dofs}")
    print(f"  moved {s['distance_m'] * 1e3:.1f} mm ({s['mean_speed_mps'] * 1e3:.1f} mm/s), "
          f"mean h {s['h_mean_m'] * 1e3:.1f} mm")
    print(f"  energy: electrical {s['energy_elec_J']:.3f} J (standby removed), mechanical "
          f"{s['energy_mech_J']:.3f} J; stalls {len(s['stalled'])}")
    print(f"  {s['steps']} steps in {s['elapsed_s']:.2f} s; largest balance residual "
          f"{s['max_residual_N']:.2g} N, inertial {s['max_inertial_N']:.2g} N")


def run_sensitivity(args) -> int:
    from ..charts.sensitivity import plot_sensitivity
    from ..multibody.sensitivity import run_sweeps
    out = output_folder(args.out, '--out')
    modes = tuple(m.strip() for m in args.modes.split(',') if m.strip())
    unknown = [m for m in modes if m not in TABLE_II]
    if unknown or not modes:
        raise ValueError(f'--modes: give burrows of {", ".join(sorted(TABLE_II))}, got '
                         f'{args.modes!r}')
    data = run_sweeps(walk=not args.no_walk, modes=modes, sled_kg=args.sled,
                      progress=lambda what: print(f'sensitivity: {what}', file=sys.stderr))
    write_text(out / 'sensitivity.json', json.dumps(_jsonable(data), indent=1) + '\n')
    plot_sensitivity(data, out / 'sensitivity.png')
    from ..multibody.sensitivity import markdown_table
    print(markdown_table(data))
    print(f'wrote {out / "sensitivity.json"} and {out / "sensitivity.png"}')
    return 0
