"""`rftgls capacity`: load capacity and slip twist of one anchor state (the paper's F and G)."""
from __future__ import annotations

import math
import time

from ..predictor import InputNames, PredictorSpec, build_predictor
from ..predictor.spec import DEFAULT_ROBOT, ROBOT_MEDIUM
from ..quantities import (
    ANGLE_DEG,
    MASS_KG,
    POSITION_M,
    TETHER_PHI_DEG,
    TETHER_YAW_DEG,
)
from ..robots.presets import ROBOTS, get_robot
from ..surfaces.registry import DEFAULT_TWISTS, METHOD_NAMES
from ..types import AnchorState, Pull
from .common import add_medium_args, finite_float, medium_from_args, print_json, twist_count


def add_state_args(p) -> None:
    p.add_argument('--robot', choices=sorted(ROBOTS), default=None,
                   help='robot (default minirquad); give its state with --h and the angles')
    # Required for a robot, refused with --mesh (state_from_args says so in one line).
    p.add_argument('--h', type=POSITION_M.arg,
                   help='height of the winch point p above the free surface, m')
    p.add_argument('--theta-b', type=ANGLE_DEG.arg, help='body pitch, deg')
    p.add_argument('--theta-l1', type=ANGLE_DEG.arg, help='proximal legs, deg')
    p.add_argument('--theta-l2', type=ANGLE_DEG.arg, help='distal legs, deg')
    p.add_argument('--phi', type=TETHER_PHI_DEG.arg, default=0.0,
                   help='tether angle, deg (0 horizontal, negative pulls down; -90..90)')
    p.add_argument('--pull', choices=[x.value for x in Pull], default='backward')
    add_medium_args(p)


STATE_OPTIONS = ('h', 'theta_b', 'theta_l1', 'theta_l2')


def state_from_args(args) -> AnchorState:
    """The state of the command line, refused (ValueError, one line) when the robot cannot be
    in it (robots.robot.StateRange): no capacity is computed for an impossible pose."""
    if getattr(args, 'state', None):
        raise ValueError('--state NAME=VALUE sets a variable of --anchor FILE.yaml; a robot '
                         'takes --h/--theta-b/--theta-l1/--theta-l2')
    args.robot = args.robot or 'minirquad'
    missing = [f'--{k.replace("_", "-")}' for k in STATE_OPTIONS if getattr(args, k) is None]
    if missing:
        raise ValueError(f'{", ".join(missing)} required for --robot {args.robot} (or give '
                         '--mesh FILE for a single rigid body)')
    state = AnchorState.from_degrees(args.h, args.theta_b, args.theta_l1, args.theta_l2)
    outside = get_robot(args.robot).state_range.violations(state)
    if outside:
        raise ValueError(f'not a {args.robot} pose: {"; ".join(outside)} (--h in m, angles '
                         'in deg)')
    return state


# The command line's flag for each input of a predictor specification (errors name these).
CLI_NAMES = InputNames(map='--map', robot='--robot', description='--anchor', state_map='--state',
                       medium='--medium', pull='--pull', live_method='--method',
                       n_twists='--twists', verb='give')


def spec_from_args(args) -> PredictorSpec:
    """The predictor of a robot command line (--robot, --method, --twists, the medium options):
    the live solver, or with --method map the map (--map, default the robot's shipped map),
    which must have been built for the command line's robot and medium."""
    args.robot = args.robot or DEFAULT_ROBOT
    if args.method == 'map':
        if any(v is not None for v in (args.xi_n, args.mu_surf, args.zeta)):
            raise ValueError('--method map answers for the medium the map was built for; drop '
                             '--xi-n/--mu-surf/--zeta or use a live method')
        return PredictorSpec(map=args.map or args.robot, robot=args.robot,
                             medium=(args.medium or ROBOT_MEDIUM[args.robot]).strip())
    args.default_medium = ROBOT_MEDIUM[args.robot]
    return PredictorSpec(robot=args.robot, medium=medium_from_args(args), model=args.model,
                         live_method=args.method, n_twists=args.twists)


def add_parser(sub) -> None:
    p = sub.add_parser('capacity', help='load capacity and slip twist of one anchor state',
                       description='Load capacity along the tether and slip twist beyond it. '
                       'JSON: slip_twist is the direction of the slip at the tether point, '
                       '(vx, vz, wy) in world axes, m/s and rad/s, scaled to unit Euclidean '
                       'norm; slip_twist_scaled is the same direction as a unit vector in the '
                       'scaled metric (vx, vz, wy*L_c), L_c = char_length_m. slip_twist_raw is '
                       'the old name of slip_twist, kept for one release (deprecated).')
    add_state_args(p)
    add_body_args(p)
    p.add_argument('--method', choices=list(METHOD_NAMES) + ['map'], default='twist-mesh')
    p.add_argument('--twists', type=twist_count, default=None,
                   help=f'sampled unit twists (default {DEFAULT_TWISTS}; 400 for direct)')
    p.add_argument('--map', help='HDF5 map file (with --method map; default: the robot\'s '
                   'shipped map)')
    p.add_argument('--json', action='store_true')
    p.set_defaults(run=run)


def run(args) -> int:
    if args.anchor is not None or args.mesh is not None or args.yaw != 0.0 or args.space != 'auto':
        return run_posed(args)
    state = state_from_args(args)
    phi = math.radians(args.phi)
    t0 = time.perf_counter()
    if args.map and args.method != 'map':
        raise ValueError('--map is used only with --method map')
    predictor = build_predictor(spec_from_args(args), CLI_NAMES)
    if args.method == 'map':
        t0 = time.perf_counter()     # a map's answer, without loading the file
    result = predictor.predict(state, phi, args.pull)
    return report(args, result, time.perf_counter() - t0, get_robot(args.robot).char_length,
                  cap_format='.3f')


# --------------------------------------------------------------------- single bodies, 6D
def add_body_args(p) -> None:
    """A single rigid body from an STL file (instead of --robot), the tether's yaw and the
    model space (docs/design/six-d.md)."""
    g = p.add_argument_group('a single rigid body (instead of --robot and its state)')
    g.add_argument('--anchor', help='anchor description YAML (with its URDF) instead of '
                   '--robot; state values by --h/--theta-b/--theta-l1/--theta-l2 for variables '
                   'of those names and --state NAME=VALUE (in the unit the YAML gives)')
    g.add_argument('--state', action='append', default=[], metavar='NAME=VALUE',
                   help='a state variable of --anchor (may repeat)')
    g.add_argument('--mesh', help='STL file of the body (binary or ASCII), closed')
    g.add_argument('--units', choices=('mm', 'm'), default='mm', help='STL units (default mm)')
    g.add_argument('--position', nargs=3, type=POSITION_M.arg, metavar=('X', 'Y', 'Z'),
                   help='mesh origin in the world, m (free surface z = 0)')
    g.add_argument('--rpy', nargs=3, type=ANGLE_DEG.arg, default=(0.0, 0.0, 0.0),
                   metavar=('R', 'P', 'Y'),
                   help='roll, pitch, yaw in degrees about the mesh origin (extrinsic x, y, z)')
    g.add_argument('--tether', nargs=3, type=POSITION_M.arg, metavar=('X', 'Y', 'Z'),
                   help='tether point on the body, m (world); twists and moments refer to it')
    g.add_argument('--mass', type=MASS_KG.arg, help='body mass, kg')
    g.add_argument('--com', nargs=3, type=POSITION_M.arg, metavar=('X', 'Y', 'Z'),
                   help='centre of mass, m (world; default: centroid of the volume)')
    p.add_argument('--yaw', type=TETHER_YAW_DEG.arg, default=0.0,
                   help='tether yaw about z, deg: the pull is Rz(yaw) (-cos phi, 0, sin phi); '
                        'a yawed pull on a robot needs the 6D path')
    p.add_argument('--space', choices=('auto', 'sagittal', '6d'), default='auto',
                   help='auto: the sagittal reduction when the posed anchor is checked to be '
                        'mirror-symmetric about the pull plane, else full 6D (default)')


def posed_from_args(args):
    """(PosedAnchor, char_length) of the command line: a rigid body (--mesh) or a robot state."""
    from ..body import RigidBody, load_body_mesh
    from ..posed import pose_robot
    if args.anchor is not None:
        return _posed_description(args)
    if args.mesh is None:
        state = state_from_args(args)
        return pose_robot(get_robot(args.robot), state, args.pull)
    if args.state:
        raise ValueError('--state NAME=VALUE sets a variable of --anchor FILE.yaml, not of '
                         '--mesh')
    given = [f'--{k.replace("_", "-")}' for k in STATE_OPTIONS if getattr(args, k) is not None]
    if args.robot is not None or given:
        raise ValueError(f'--mesh describes the whole body: drop {", ".join(given or ["--robot"])}')
    need = [f'--{k}' for k in ('position', 'tether', 'mass') if getattr(args, k) is None]
    if need:
        raise ValueError(f'--mesh needs {", ".join(need)} (m, m, kg)')
    if not args.mass >= 0.0:
        raise ValueError(f'--mass must be >= 0 kg, got {args.mass:g}')
    mesh = load_body_mesh(args.mesh, units=args.units)
    body = RigidBody(name=str(args.mesh), mesh=mesh, mass=args.mass)
    return body.pose(args.position, [math.radians(a) for a in args.rpy], args.tether,
                      com_world=args.com)


def _posed_description(args):
    """The posed anchor of an anchor description at the command line's state values."""
    from ..description import load_description
    if args.mesh is not None or args.robot is not None:
        raise ValueError('--anchor describes the whole anchor: drop --mesh/--robot')
    desc = load_description(args.anchor)
    given: dict[str, float] = {}
    for item in args.state:
        name, sep, value = item.partition('=')
        if not sep:
            raise ValueError(f'--state wants NAME=VALUE, got {item!r}')
        try:
            given[name.strip()] = finite_float(value)
        except Exception:
            raise ValueError(f'--state {item!r}: not a finite number') from None
    for k in STATE_OPTIONS:
        if getattr(args, k) is not None:
            given[k] = getattr(args, k)
    unknown = sorted(set(given) - set(desc.state_names))
    if unknown:
        raise ValueError(f'{args.anchor}: no state variable {", ".join(unknown)} (it has '
                         f'{", ".join(desc.state_names)})')
    missing = [n for n in desc.state_names if n not in given]
    if missing:
        raise ValueError(f'{args.anchor}: give {", ".join(missing)} (--state NAME=VALUE or '
                         'the option of that name)')
    values = {v.name: v.to_si(given[v.name]) for v in desc.state}
    outside = desc.violations(values)
    if outside:
        raise ValueError(f'not a {desc.name} pose: {"; ".join(outside)}')
    args.description_medium = desc.medium
    args.description_symmetry = desc.symmetry
    return desc.pose(values, args.pull)


def run_posed(args) -> int:
    """Capacity of a rigid body or of a robot under a yawed pull (6D world twists)."""
    from ..posed import PosedAnchorSolver
    if args.method == 'map' or args.map:
        raise ValueError('--method map answers sagittal robot pulls only: use a live method '
                         'with --mesh, --yaw or --space')
    args.default_medium = (ROBOT_MEDIUM[args.robot or DEFAULT_ROBOT] if args.mesh is None
                           else 'glass_beads')
    posed = posed_from_args(args)
    args.default_medium = getattr(args, 'description_medium', args.default_medium)
    if (getattr(args, 'description_symmetry', '') == 'sagittal' and args.space == 'auto'
            and args.yaw == 0.0):
        # A claimed symmetry asks for the sagittal path, which checks it first (status
        # invalid_input, not_symmetric, when the posed facets or the centre of mass lack it).
        args.space = 'sagittal'
    t0 = time.perf_counter()
    solver = PosedAnchorSolver(medium_from_args(args), model=args.model, method=args.method,
                               n_twists=args.twists, space=args.space)
    result = solver.solve(posed, math.radians(args.phi), math.radians(args.yaw))
    return report(args, result, time.perf_counter() - t0, posed.char_length, cap_format='.4g',
                  space=result.space, always_detail=True)


_TWIST_NAMES = {3: 'vx, vz, wy*L_c', 6: 'vx, vy, vz, wx*L_c, wy*L_c, wz*L_c'}


def report(args, result, elapsed_s: float, char_length_m: float, *, cap_format: str,
           space: str | None = None, always_detail: bool = False) -> int:
    """Print one capacity answer: JSON with --json, else lines for people (capacity in N with
    cap_format, status, method, the space when given, time; the scaled slip twist, flags, and
    reason: detail, the detail alone too when always_detail). Returns the exit status 0."""
    if args.json:
        print_json(result_json(result, elapsed_s, char_length_m))
        return 0
    cap = 'none' if result.capacity_N is None else f'{result.capacity_N:{cap_format}} N'
    where = f'space {space}  ' if space is not None else ''
    print(f'capacity {cap}  status {result.status.value}  method {result.method}  '
          f'{where}({1e3 * elapsed_s:.1f} ms)')
    if result.slip_twist_scaled:
        names = _TWIST_NAMES[len(result.slip_twist_scaled)]
        print(f'slip twist (scaled {names}): '
              + ' '.join(f'{v:+.4f}' for v in result.slip_twist_scaled))
    if result.flags:
        print('flags: ' + ', '.join(result.flags))
    if result.reason:
        print(f'reason: {result.reason}: {result.detail}')
    elif always_detail:
        print(result.detail)
    return 0


def result_json(result, elapsed_s: float, char_length_m: float) -> dict:
    """The JSON of every `rftgls capacity` answer (robot, anchor or single body): capacity N,
    the slip twist (3 or 6 components, world axes at the tether point: (vx, vz, wy) or (vx, vy,
    vz, wx, wy, wz), m/s and rad/s, unit Euclidean norm) and the same direction in the scaled
    metric, status, timing and flags. slip_twist_raw: slip_twist's old name, one release."""
    scaled = list(result.slip_twist_scaled) if result.slip_twist_scaled else None
    raw = list(result.slip_twist) if result.slip_twist else None
    return {'capacity_N': result.capacity_N,
            'slip_twist_scaled': scaled,
            'slip_twist': raw,
            'slip_twist_raw': raw,   # deprecated: the old key of slip_twist, one release
            'status': result.status.value, 'method': result.method, 'elapsed_s': elapsed_s,
            'reason': result.reason, 'detail': result.detail, 'char_length_m': char_length_m,
            'flags': list(result.flags), 'twist_spread_rad': result.twist_spread_rad}
