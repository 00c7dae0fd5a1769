"""`rftgls wrench`: the RFT wrench on a mesh placed in the medium, for one twist."""
from __future__ import annotations

import numpy as np

from ..geometry.stl import MeshError, read_stl
from ..geometry.transforms import rpy_matrix
from ..geometry.validate import clean_mesh
from ..quantities import ANGLE_DEG, ANGULAR_SPEED_RAD_S, LINEAR_SPEED_M_S, POSITION_M
from ..rft.engine import BuriedBody
from ..rft.models import make_model
from .common import add_medium_args, finite_float, medium_from_args, print_json

# Below this the twist has no usable direction (1 nm/s or 1 nrad/s).
MIN_TWIST_NORM = 1e-9


def add_parser(sub) -> None:
    p = sub.add_parser('wrench', help='RFT force and moment on a mesh for one twist',
                       description='Resistive wrench on an STL body in the medium (free '
                       'surface z = 0, world z up) for one twist.')
    p.add_argument('--mesh', required=True, help='STL file (binary or ASCII)')
    p.add_argument('--units', choices=('mm', 'm'), default='mm', help='STL units (default mm)')
    p.add_argument('--position', nargs=3, type=POSITION_M.arg, default=(0.0, 0.0, 0.0),
                   metavar=('X', 'Y', 'Z'), help='mesh origin in the world, m')
    p.add_argument('--rpy', nargs=3, type=ANGLE_DEG.arg, default=(0.0, 0.0, 0.0),
                   metavar=('R', 'P', 'Y'),
                   help='roll, pitch, yaw in degrees about the mesh origin (extrinsic x, y, z)')
    p.add_argument('--twist', nargs=6, type=finite_float, required=True,
                   metavar=('VX', 'VY', 'VZ', 'WX', 'WY', 'WZ'),
                   help='world-frame twist at the reference point: m/s and rad/s (RFT is '
                        f'quasi-static: |v| <= {LINEAR_SPEED_M_S.hi:g} m/s, |w| <= '
                        f'{ANGULAR_SPEED_RAD_S.hi:g} rad/s)')
    p.add_argument('--ref', nargs=3, type=POSITION_M.arg, default=None, metavar=('X', 'Y', 'Z'),
                   help='reference point of twist and moment, m (default: placed mesh origin)')
    add_medium_args(p, default='glass_beads')
    p.add_argument('--json', action='store_true', help='print JSON')
    p.set_defaults(run=run)


def run(args) -> int:
    medium = medium_from_args(args)
    model = make_model(args.model, medium)
    for i, v in enumerate(args.twist):
        q = LINEAR_SPEED_M_S if i < 3 else ANGULAR_SPEED_RAD_S
        q.check(v, f'--twist {"VX VY VZ WX WY WZ".split()[i]}')
    twist = np.asarray(args.twist, dtype=float)
    norm = float(np.linalg.norm(twist))
    if not norm >= MIN_TWIST_NORM:
        # RFT reads only the direction, but a norm this small underflows in the facet
        # velocities (1e-200 squared is 0) and would answer 0 N: invalid input, not a value.
        raise ValueError(f'invalid_input: twist has no direction (norm {norm:.3g} < '
                         f'{MIN_TWIST_NORM:g}; m/s and rad/s)')
    # Repair what a CAD export gets wrong: degenerate facets (dropped with a warning) and
    # inconsistent or inward winding (RFT needs outward normals).
    try:
        mesh, report = clean_mesh(read_stl(args.mesh, units=args.units))
    except MeshError as exc:
        if str(args.mesh) in str(exc):
            raise
        raise MeshError(f'{args.mesh}: {exc}') from None
    position = np.asarray(args.position, dtype=float)
    rot = rpy_matrix(*np.radians(args.rpy))
    facets = mesh.facets().transformed(rot, position)
    ref = position if args.ref is None else np.asarray(args.ref, dtype=float)
    body = BuriedBody(facets, model, ref=ref)
    w = body.wrench(twist)
    result = {'force_N': w[:3].tolist(), 'moment_Nm': w[3:].tolist(),
              'facets_total': body.facets_total, 'facets_active': body.facets_active,
              'model': model.name, 'medium': medium.name}
    if args.json:
        print_json(result)
    else:
        print(f"force  [N]   {w[0]: .6g} {w[1]: .6g} {w[2]: .6g}")
        print(f"moment [N m] {w[3]: .6g} {w[4]: .6g} {w[5]: .6g}  about {ref.tolist()}")
        print(f"facets: {body.facets_active} buried of {body.facets_total}; "
              f"model {model.name}, medium {medium.name}")
    return 0
