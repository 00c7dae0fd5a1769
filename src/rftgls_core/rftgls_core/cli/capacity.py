"""`rftgls capacity`: load capacity and slip twist of one anchor state (the paper's F and G)."""
from __future__ import annotations

import math
import time

from ..anchor import DEFAULT_TWISTS, AnchorModel
from ..robots.presets import ROBOTS, get_robot
from ..surfaces.registry import METHOD_NAMES
from ..types import AnchorState, Pull
from .common import add_medium_args, finite_float, medium_from_args, print_json, twist_count

DEFAULT_MEDIUM = {'prototype': 'glass_beads', 'minirquad': 'm90_sand'}


def add_state_args(p) -> None:
    p.add_argument('--robot', choices=sorted(ROBOTS), default='minirquad')
    p.add_argument('--h', type=finite_float, required=True,
                   help='height of the winch point p above the free surface, m')
    p.add_argument('--theta-b', type=finite_float, required=True, help='body pitch, deg')
    p.add_argument('--theta-l1', type=finite_float, required=True, help='proximal legs, deg')
    p.add_argument('--theta-l2', type=finite_float, required=True, help='distal legs, deg')
    p.add_argument('--phi', type=finite_float, default=0.0,
                   help='tether angle, deg (0 horizontal, negative pulls down)')
    p.add_argument('--pull', choices=[x.value for x in Pull], default='backward')
    add_medium_args(p)


def state_from_args(args) -> AnchorState:
    """The state of the command line, refused (ValueError, one line) when the robot cannot be
    in it (robots.model.StateRange): no capacity is computed for an impossible pose."""
    state = AnchorState.from_degrees(args.h, args.theta_b, args.theta_l1, args.theta_l2)
    outside = get_robot(args.robot).state_range.violations(state)
    if outside:
        raise ValueError(f'not a {args.robot} pose: {"; ".join(outside)} (--h in m, angles '
                         'in deg)')
    return state


def map_from_args(args):
    """The map of --map (or the robot's shipped map), refused when it was built for another
    robot or medium than the command line's: a map answers only for what it was built for."""
    from ..maps import CapacityMap, resolve_map
    cmap = CapacityMap.load(resolve_map(args.map, robot=args.robot))
    if cmap.robot_name != args.robot:
        raise ValueError(f'{cmap.source}: map is for robot {cmap.robot_name!r}, not '
                         f'--robot {args.robot}')
    if any(v is not None for v in (args.xi_n, args.mu_surf, args.zeta)):
        raise ValueError('--method map answers for the medium the map was built for; drop '
                         '--xi-n/--mu-surf/--zeta or use a live method')
    want = (args.medium or DEFAULT_MEDIUM[args.robot]).strip()
    if want.lower().endswith('.json') or want.lower() != cmap.medium_name.lower():
        raise ValueError(f'{cmap.source}: map is for medium {cmap.medium_name!r}, not '
                         f'{want!r}')
    return cmap


def model_from_args(args, method: str | None = None) -> AnchorModel:
    args.default_medium = DEFAULT_MEDIUM[args.robot]
    return AnchorModel(get_robot(args.robot), medium_from_args(args), model=args.model,
                       method=method or args.method, n_twists=args.twists)


def add_parser(sub) -> None:
    p = sub.add_parser('capacity', help='load capacity and slip twist of one anchor state',
                       description='Load capacity along the tether and slip twist beyond it. '
                       'JSON: slip_twist_scaled is a unit vector in the scaled metric (vx, vz, '
                       'wy*L_c), L_c = char_length_m of the robot; slip_twist_raw is (vx, vz, '
                       'wy) in m/s and rad/s scaled to unit Euclidean norm. slip_twist is the '
                       'old name of slip_twist_scaled, kept for one release (deprecated).')
    add_state_args(p)
    p.add_argument('--method', choices=list(METHOD_NAMES) + ['map'], default='twist-mesh')
    p.add_argument('--twists', type=twist_count, default=None,
                   help=f'sampled unit twists (default {DEFAULT_TWISTS}; 400 for direct)')
    p.add_argument('--map', help='HDF5 map file (with --method map; default: the robot\'s '
                   'shipped map)')
    p.add_argument('--json', action='store_true')
    p.set_defaults(run=run)


def run(args) -> int:
    state = state_from_args(args)
    phi = math.radians(args.phi)
    t0 = time.perf_counter()
    if args.map and args.method != 'map':
        raise ValueError('--map is used only with --method map')
    if args.method == 'map':
        cmap = map_from_args(args)
        t0 = time.perf_counter()
        result = cmap.query(state, phi, args.pull)
        char_length = get_robot(cmap.robot_name).char_length
    else:
        model = model_from_args(args)
        result = model.predict(state, phi, args.pull)
        char_length = model.robot.char_length
    elapsed = time.perf_counter() - t0
    scaled = list(result.slip_twist_scaled) if result.slip_twist_scaled else None
    out = {'capacity_N': result.capacity_N,
           'slip_twist_scaled': scaled,
           'slip_twist': scaled,   # deprecated: the old key of slip_twist_scaled, one release

           'slip_twist_raw': list(result.slip_twist) if result.slip_twist else None,
           'status': result.status.value, 'method': result.method, 'elapsed_s': elapsed,
           'reason': result.reason, 'detail': result.detail, 'char_length_m': char_length,
           'flags': list(result.flags), 'twist_spread_rad': result.twist_spread_rad}
    if args.json:
        print_json(out)
    else:
        cap = 'none' if result.capacity_N is None else f'{result.capacity_N:.3f} N'
        print(f'capacity {cap}  status {result.status.value}  method {result.method}  '
              f'({1e3 * elapsed:.1f} ms)')
        if result.slip_twist_scaled:
            print('slip twist (scaled vx, vz, wy*L_c): '
                  + ' '.join(f'{v:+.4f}' for v in result.slip_twist_scaled))
        if result.flags:
            print('flags: ' + ', '.join(result.flags))
        if result.reason:
            print(f'reason: {result.reason}: {result.detail}')
    return 0
