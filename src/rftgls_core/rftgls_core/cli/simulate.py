"""`rftgls simulate pull`: quasi-static trajectory of a failing anchor under a steady pull."""
from __future__ import annotations

import csv
import io
import math
import sys

from rftgls_conventions.safe_write import output_file, write_text

from ..charts.figure_io import figure_path
from ..predictor import Predictor, build_predictor
from ..quantities import PULL_SPEED_M_S, SLIP_STEP_M, SLIP_TRAVEL_M
from ..sim.trajectory import simulate_pull
from .capacity import CLI_NAMES, add_body_args, add_state_args, spec_from_args, state_from_args
from .common import twist_count


def add_parser(sub) -> None:
    p = sub.add_parser('simulate', help='quasi-static trajectories (simulate pull, burrow, walk)')
    sub2 = p.add_subparsers(dest='what', required=True)
    q = sub2.add_parser('pull', help='slip of an anchor held at its capacity by a steady pull')
    add_state_args(q)
    add_body_args(q)
    q.add_argument('--method', choices=['direct', 'twist-mesh', 'map'], default='direct')
    q.add_argument('--map', help='HDF5 map (with --method map; default: the robot\'s shipped map)')
    q.add_argument('--twists', type=twist_count, default=None)
    q.add_argument('--integrator', choices=['euler', 'heun'], default='heun')
    q.add_argument('--step', type=SLIP_STEP_M.arg, default=0.001, help='path of p per step, m')
    q.add_argument('--max-travel', type=SLIP_TRAVEL_M.arg, default=0.08, help='m')
    q.add_argument('--speed', type=PULL_SPEED_M_S.arg, default=0.001,
                   help='pull speed that turns path length into time, m/s (default 1 mm/s)')
    q.add_argument('--out', required=True, help='CSV file')
    q.add_argument('--plot', help='PNG file (force, z and thetaB against x, like Fig. 8)')
    q.set_defaults(run=run)
    from .simulate_gait import add_parsers
    add_parsers(sub2)


def run(args) -> int:
    from tqdm import tqdm

    out = output_file(args.out, '--out')     # both outputs checked before any work
    if args.plot:
        figure_path(args.plot, '--plot')
    if args.anchor is not None:
        raise ValueError('simulate pull follows --robot or --mesh; an --anchor description is '
                         'simulated by the lab tools (rftgls_lab_synthetic --anchor)')
    body = None
    predictor: Predictor
    if args.mesh is not None:
        body, state = _body_from_args(args)
    else:
        state = state_from_args(args)
    phi = math.radians(args.phi)
    if not (args.step > 0 and args.max_travel > 0 and args.speed > 0):
        raise ValueError('--step, --max-travel and --speed must be > 0')
    if args.max_travel / args.step > 100_000:
        raise ValueError(f'--max-travel / --step gives {args.max_travel / args.step:.3g} steps; '
                         'at most 100000')
    if args.map and args.method != 'map':
        raise ValueError('--map is used only with --method map')
    if body is not None:
        from ..posed import PosedAnchorSolver
        from ..sim.body_pull import BodyPredictor
        from .common import medium_from_args
        if args.method == 'map' or args.map:
            raise ValueError('--method map answers the shipped robots only; use direct or '
                             'twist-mesh with --mesh')
        predictor = BodyPredictor(body, PosedAnchorSolver(medium_from_args(args), model=args.model,
                                                          method=args.method,
                                                          n_twists=args.twists))
        plate = lambda st: -st.h   # noqa: E731 (stop when the tether point reaches the surface)
        name = str(args.mesh)
    else:
        from ..robots.presets import get_robot
        predictor = build_predictor(spec_from_args(args), CLI_NAMES)
        robot = get_robot(args.robot)
    if body is None:
        plate = lambda st: robot.pose(st, args.pull).plate_min_z  # noqa: E731
        name = robot.name
    bar = tqdm(total=int(args.max_travel / args.step), unit='step', file=sys.stderr,
               desc='slip', leave=False)
    traj = simulate_pull(predictor, state, phi, args.pull, plate, step=args.step,
                         integrator=args.integrator, max_travel=args.max_travel,
                         progress=lambda k: bar.update(1))
    bar.close()
    if body is not None:
        traj.stop_reason = traj.stop_reason.replace('body plate', 'tether point')
    text = io.StringIO(newline='')
    w = csv.writer(text)
    w.writerow(['t_s', 's_m', 'x_m', 'z_m', 'theta_b_rad', 'force_N', 'status'])
    for p in traj.points:
        w.writerow([p.s_m / args.speed, p.s_m, p.x_m, p.z_m, p.theta_b,
                    '' if p.force_N is None else p.force_N, p.status])
    write_text(out, text.getvalue())
    print(f'{len(traj.points)} points, stopped: {traj.stop_reason}; wrote {out}')
    if args.plot:
        from ..charts.trajectory import plot_trajectories
        plot_trajectories({f'{args.method}, {args.integrator}': traj}, args.plot,
                          title=f'{name}, {args.pull} pull, phi = {args.phi:.0f} deg')
        print(f'wrote {args.plot}')
    return 0


def _body_from_args(args):
    """(BodyAnchor, initial state) of a rigid body on the command line: the body frame B is
    the world frame moved to the tether point at the initial pose (h = the tether's height,
    thetaB = 0); the slip turns it about y (a sagittal trajectory: the pull must lie in a
    mirror plane of the body, which every step checks; yaw is not supported here)."""
    import numpy as np

    from ..body import RigidBody, load_body_mesh
    from ..geometry.transforms import rpy_matrix
    from ..sim.body_pull import BodyAnchor
    from ..types import AnchorState
    from .capacity import posed_from_args
    if args.yaw != 0.0 or args.space != 'auto':
        raise ValueError('simulate pull follows sagittal slips only: drop --yaw and --space')
    args.default_medium = 'glass_beads'
    start = posed_from_args(args)       # checks the mesh, the tether and the burial
    p = start.ref
    mesh = load_body_mesh(args.mesh, units=args.units)
    rot = rpy_matrix(*np.radians(args.rpy))
    mesh_b = mesh.transformed(rot, np.asarray(args.position, dtype=float) - p)
    com_b = tuple(float(v) for v in np.asarray(start.com) - p)
    body = RigidBody(str(args.mesh), mesh_b, args.mass, com_body=(com_b[0], com_b[1], com_b[2]))
    return BodyAnchor(body), AnchorState(float(p[2]), 0.0, 0.0, 0.0)
