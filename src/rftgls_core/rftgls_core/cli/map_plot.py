"""`rftgls map plot`: a capacity map's slice over two state axes as a heatmap (PNG).

    rftgls map plot FILE --x theta_l1 --y theta_l2 [--h MM] [--theta-b DEG] [--theta-l1 DEG]
                    [--theta-l2 DEG] [--phi DEG] [--pull P] [--n 121] --out SLICE.png

The two plotted axes span the map's grid; the other state axes and phi are fixed at the given
values (default: the middle grid node; mm and degrees, like `rftgls map build`). Each pixel is
the map's own answer (CapacityMap.query_batch): capacity in N where the status has a value;
cells the map calls `unsupported` (the legs cannot hold the robot's weight) are hatched grey
and the support edge, the border between a value and `unsupported`, is drawn in red; anything
else without a value (degenerate, ...) is white. Grid nodes are the black dots. A described
map (`map build --anchor`) is plotted over two of its own state variables, the others fixed
by `--at NAME=VALUE` (cli/map_described.py).
"""
from __future__ import annotations

import math

import numpy as np

from ..quantities import ANGLE_DEG, POSITION_MM, TETHER_PHI_DEG, bounded_int

AXES = ('h', 'theta_b', 'theta_l1', 'theta_l2')
FLAG = {'h': 'h_mm', 'theta_b': 'theta_b_deg', 'theta_l1': 'theta_l1_deg',
        'theta_l2': 'theta_l2_deg'}
LABEL = {'h': 'h [mm]', 'theta_b': 'thetaB [deg]', 'theta_l1': 'thetaL1 [deg]',
         'theta_l2': 'thetaL2 [deg]'}


def add_plot_parser(msub) -> None:
    p = msub.add_parser('plot', help='capacity heatmap over two state axes, support edge marked')
    p.add_argument('file', help='map (.h5), a shipped map name or a robot name')
    p.add_argument('--x', default='theta_l1', help=f'horizontal axis ({", ".join(AXES)}; '
                   'of a described map: one of its state variables)')
    p.add_argument('--y', default='theta_l2', help='vertical axis')
    p.add_argument('--at', action='append', metavar='NAME=VALUE',
                   help="a described map's fixed state variable, in its unit (may repeat)")
    p.add_argument('--h', dest='h_mm', type=POSITION_MM.arg, help='fixed h, mm')
    p.add_argument('--theta-b', dest='theta_b_deg', type=ANGLE_DEG.arg,
                   help='fixed thetaB, deg')
    p.add_argument('--theta-l1', dest='theta_l1_deg', type=ANGLE_DEG.arg,
                   help='fixed thetaL1, deg')
    p.add_argument('--theta-l2', dest='theta_l2_deg', type=ANGLE_DEG.arg,
                   help='fixed thetaL2, deg')
    p.add_argument('--phi', dest='phi_deg', type=TETHER_PHI_DEG.arg, help='tether angle, deg')
    p.add_argument('--pull', default=None, help='forward | backward (default: the first)')
    p.add_argument('--n', type=bounded_int(8, 1000, '--n'), default=121,
                   help='pixels per axis (default: %(default)s)')
    p.add_argument('--out', required=True, help='output PNG')
    p.set_defaults(run=run_plot)


def _si(axis: str, value: float) -> float:
    return value * 1e-3 if axis == 'h' else math.radians(value)


def _shown(axis: str, values: np.ndarray) -> np.ndarray:
    return values * 1e3 if axis == 'h' else np.degrees(values)


def map_slice(cmap, x: str, y: str, fixed: dict[str, float], phi: float, pull: str, n: int):
    """(xs, ys, capacity (n, n) N with NaN, unsupported (n, n) bool): the map over its grid
    range of axes x and y (SI), the other axes at ``fixed`` (SI)."""
    from ..maps.hdf5 import STATUS_NAMES
    ax = cmap.axes
    xs = np.linspace(ax[x][0], ax[x][-1], n)
    ys = np.linspace(ax[y][0], ax[y][-1], n)
    X, Y = np.meshgrid(xs, ys)
    states = np.empty((n * n, 4))
    for k, name in enumerate(AXES):
        states[:, k] = X.ravel() if name == x else Y.ravel() if name == y else fixed[name]
    ans = cmap.query_batch(states, phi, pull)
    unsupported = ans.status == STATUS_NAMES.index('unsupported')
    return xs, ys, ans.capacity_N.reshape(n, n), unsupported.reshape(n, n)


def run_plot(args) -> int:
    from ..charts.figure_io import pyplot
    from ..charts.map_slice import save_slice
    from ..maps import CapacityMap, resolve_map
    from ..maps.described import is_described_map
    if is_described_map(args.file):   # a map over a description's variables
        from .map_described import plot as described_plot
        return described_plot(args)
    for flag, a in (('--x', args.x), ('--y', args.y)):
        if a not in AXES:
            raise ValueError(f'{flag} must be one of {", ".join(AXES)}, got {a!r}')
    if args.at:
        raise ValueError('--at fixes a described map\'s variables; use --h/--theta-* here')
    if args.x == args.y:
        raise ValueError(f'--x and --y must differ, both are {args.x!r}')
    if not 8 <= args.n <= 1000:
        raise ValueError(f'--n must be in [8, 1000], got {args.n}')
    cmap = CapacityMap.load(resolve_map(args.file))
    ax = cmap.axes
    fixed = {a: (_si(a, getattr(args, FLAG[a])) if getattr(args, FLAG[a]) is not None
                 else float(ax[a][len(ax[a]) // 2])) for a in AXES}
    for a in AXES:
        v = fixed[a]
        if a not in (args.x, args.y) and not (ax[a][0] <= v <= ax[a][-1]):
            raise ValueError(f'{a} = {_shown(a, np.array(v)):.4g} lies outside the map '
                             f'({_shown(a, ax[a][0]):.4g} .. {_shown(a, ax[a][-1]):.4g})')
    phi = math.radians(args.phi_deg) if args.phi_deg is not None else float(
        cmap.phis[len(cmap.phis) // 2])
    pull = args.pull or cmap.pulls[0]
    if pull not in cmap.pulls:
        raise ValueError(f'pull {pull!r} not in this map (has {", ".join(cmap.pulls)})')
    xs, ys, cap, unsup = map_slice(cmap, args.x, args.y, fixed, phi, pull, args.n)
    plt = pyplot()
    fig, axp = plt.subplots(figsize=(7.5, 6))
    sx, sy = _shown(args.x, xs), _shown(args.y, ys)
    mesh = axp.pcolormesh(sx, sy, np.ma.masked_invalid(cap), shading='auto', cmap='viridis')
    fig.colorbar(mesh, ax=axp, label='capacity along the tether [N]')
    if unsup.any():
        axp.contourf(sx, sy, unsup.astype(float), levels=[0.5, 1.5], colors='none',
                     hatches=['//'])
        axp.contourf(sx, sy, unsup.astype(float), levels=[0.5, 1.5], colors=['0.75'],
                     alpha=0.5)
        valued = np.isfinite(cap).astype(float)
        axp.contour(sx, sy, valued - unsup.astype(float), levels=[0.0], colors='red',
                    linewidths=1.5)
        axp.plot([], [], color='red', label='support edge')
        axp.fill([], [], color='0.75', hatch='//', label='unsupported')
    gx, gy = np.meshgrid(_shown(args.x, ax[args.x]), _shown(args.y, ax[args.y]))
    axp.plot(gx.ravel(), gy.ravel(), 'k.', ms=3, label='grid nodes')
    axp.set_xlabel(LABEL[args.x])
    axp.set_ylabel(LABEL[args.y])
    others = ', '.join(f'{LABEL[a].split()[0]} {float(_shown(a, np.array(fixed[a]))):.3g}'
                       for a in AXES if a not in (args.x, args.y))
    axp.set_title(f'{cmap.robot_name}, {cmap.medium_name}, {pull} pull, phi '
                  f'{math.degrees(phi):.0f} deg; {others}', fontsize=9)
    return save_slice(fig, axp, args.out, cap, unsup)
