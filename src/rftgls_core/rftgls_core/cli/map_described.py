"""`rftgls map accuracy | refine | plot` on a described map (maps/described.py, built by
`rftgls map build --anchor FILE.yaml`):

    rftgls map accuracy FILE.h5 --anchor FILE.yaml [--samples N] [--reference direct] [--json]
    rftgls map refine FILE.h5 --anchor FILE.yaml --out NEW.h5 [--tol PCT] [--samples N]
    rftgls map plot FILE.h5 --x NAME --y NAME [--at NAME=VALUE ...] [--phi DEG] --out PNG

accuracy and refine solve the description live, so they need it (`--anchor`, checked to be
the map's own by its identity); plot reads the map alone. Values are in the description's
units (m or deg, as its YAML declares them). The robot maps' options that a described map
has no data for (--random) are refused with one line; --support-edge is the same opt-in
zeros rule as for the robot maps (DescribedMap).
"""
from __future__ import annotations

import math

import numpy as np


def local_workers(workers: int | None) -> int:
    """--workers of a described build: None = every usable core (maps/build.py's rule)."""
    from ..maps.build import default_workers
    if workers is not None and workers < 1:
        raise ValueError(f'--workers must be >= 1, got {workers}')
    return default_workers() if workers is None else workers


def _load(args, support_edge: bool = False):
    """(DescribedMap, AnchorDescription) of FILE and --anchor (ValueError, one line)."""
    from ..description import load_description
    from ..maps.described import DescribedMap, check_identity
    if not getattr(args, 'anchor', None):
        raise ValueError(f'{args.file} is a described map: give --anchor FILE.yaml, the '
                         'description it was built for (it is solved live for the check)')
    cmap = DescribedMap.load(args.file, support_edge=support_edge)
    desc = load_description(args.anchor)
    check_identity(cmap, desc)
    return cmap, desc


def accuracy(args):
    """The AccuracyReport of `map accuracy` for a described map."""
    from ..maps.described_accuracy import described_accuracy
    if args.random:
        raise ValueError('--random samples a robot\'s ranges; for a described map use '
                         '--samples')
    cmap, desc = _load(args, support_edge=args.support_edge)
    return described_accuracy(cmap, desc, samples=args.samples, seed=args.seed,
                              reference=args.reference, progress=not args.quiet)


def refine(args) -> int:
    """`map refine` of a described map: the intervals, then the refined map rebuilt with the
    same description, medium, method and twist count."""
    import shlex

    from ..maps.described import map_medium, save_described_map
    from ..maps.described_accuracy import described_interval_errors, refined_described_grid
    from ..maps.described_build import build_described_map
    cmap, desc = _load(args)
    errors = described_interval_errors(cmap, desc, samples=args.samples, seed=args.seed,
                                       progress=not args.quiet)
    g = cmap.grid
    grid = refined_described_grid(g, errors, args.tol)
    unit = dict(zip(g.names, g.units))
    for e in errors:
        fac = 180.0 / math.pi if unit[e.axis] == 'deg' else 1.0
        flag = '  <- refine' if math.isfinite(e.p95_pct) and e.p95_pct > args.tol else ''
        print(f'{e.axis:9s} {e.lo * fac:9.4g} .. {e.hi * fac:9.4g} {unit[e.axis]:3s}  p95 '
              f'{e.p95_pct:6.2f} %  ({e.compared} compared, {e.mismatched} status differ){flag}')
    added = grid.n_states - g.n_states
    print(f'{g.n_states} -> {grid.n_states} states (+{added})')
    if args.dry_run or added == 0:
        return 0
    at = cmap.data.attrs
    medium = map_medium(cmap.data)
    parts = ['rftgls', 'map', 'build', '--anchor', str(args.anchor), '--medium', medium.name,
             '--method', str(at['method']), '--n-twists', str(int(at['n_twists']))]
    for n, u, a in zip(grid.names, grid.units, grid.axes):
        fac = 180.0 / math.pi if u == 'deg' else 1.0
        parts.append(f'--axis={n}=' + ','.join(f'{v * fac:.6g}' for v in a))
    parts.append('--phi=' + ','.join(f'{math.degrees(v):.6g}' for v in grid.phi))
    parts += ['--pulls', ','.join(grid.pulls)]
    data = build_described_map(desc, medium, grid, method=str(at['method']),
                               model=str(at['rft_model']), n_twists=int(at['n_twists']),
                               progress=not args.quiet, command=shlex.join(parts),
                               workers=local_workers(args.workers))
    print(f'wrote {save_described_map(args.out, data)}')
    return 0


def _at(items: list[str], grid) -> dict[str, float]:
    """--at NAME=VALUE (the description's unit) -> SI by name."""
    unit = dict(zip(grid.names, grid.units))
    out = {}
    for item in items:
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep or name not in unit:
            raise ValueError(f'--at wants NAME=VALUE with NAME one of {", ".join(grid.names)}, '
                             f'got {item!r}')
        try:
            v = float(text)
        except ValueError:
            raise ValueError(f'--at {name}: not a number: {text!r}') from None
        out[name] = math.radians(v) if unit[name] == 'deg' else v
    return out


def plot(args) -> int:
    """`map plot` of a described map: capacity over two of its state variables (the others
    at --at or their middle node), the map's own answers (DescribedMap.query_batch); cells
    with status `unsupported` hatched, other statuses without a value white."""
    from ..charts.figure_io import pyplot
    from ..charts.map_slice import save_slice
    from ..maps.described import DescribedMap
    from ..maps.hdf5 import STATUS_NAMES
    cmap = DescribedMap.load(args.file)
    g = cmap.grid
    for flag in ('h_mm', 'theta_b_deg', 'theta_l1_deg', 'theta_l2_deg'):
        if getattr(args, flag, None) is not None:
            raise ValueError(f'{args.file} is a described map: fix its variables with --at '
                             f'NAME=VALUE ({", ".join(g.names)}), not --{flag.rsplit("_", 1)[0]}')
    x = args.x if args.x in g.names else None
    y = args.y if args.y in g.names else None
    if len(g.names) < 2:
        raise ValueError(f'{args.file} has one state variable ({g.names[0]}): nothing to plot '
                         'over two axes')
    if x is None or y is None or x == y:
        raise ValueError(f'--x and --y must be two different state variables of the map '
                         f'({", ".join(g.names)}), got {args.x!r} and {args.y!r}')
    ax = dict(zip(g.names, g.axes))
    unit = dict(zip(g.names, g.units))
    fixed = {n: float(a[len(a) // 2]) for n, a in ax.items()}
    at = _at(args.at or [], g)
    if set(at) & {x, y}:
        raise ValueError(f'--at {", ".join(sorted(set(at) & {x, y}))}: that variable is '
                         'plotted (--x/--y), not fixed')
    fixed.update(at)

    def shown(n: str, v):
        return np.degrees(v) if unit[n] == 'deg' else np.asarray(v)
    for n, v in fixed.items():
        if n not in (x, y) and not (ax[n][0] <= v <= ax[n][-1]):
            raise ValueError(f'{n} = {float(shown(n, v)):.4g} {unit[n]} lies outside the map '
                             f'({float(shown(n, ax[n][0])):.4g} .. '
                             f'{float(shown(n, ax[n][-1])):.4g})')
    phi = math.radians(args.phi_deg) if args.phi_deg is not None else float(
        g.phi[len(g.phi) // 2])
    pull = args.pull or g.pulls[0]
    if pull not in g.pulls:
        raise ValueError(f'pull {pull!r} not in this map (has {", ".join(g.pulls)})')
    xs = np.linspace(ax[x][0], ax[x][-1], args.n)
    ys = np.linspace(ax[y][0], ax[y][-1], args.n)
    X, Y = np.meshgrid(xs, ys)
    values = np.column_stack([X.ravel() if n == x else Y.ravel() if n == y
                              else np.full(X.size, fixed[n]) for n in g.names])
    cap, code = cmap.query_batch(values, phi, pull, cmap.description_sha256)
    cap = cap.reshape(args.n, args.n)
    unsup = (code == STATUS_NAMES.index('unsupported')).reshape(args.n, args.n)
    plt = pyplot()
    fig, axp = plt.subplots(figsize=(7.5, 6))
    sx, sy = shown(x, xs), shown(y, ys)
    mesh = axp.pcolormesh(sx, sy, np.ma.masked_invalid(cap), shading='auto', cmap='viridis')
    fig.colorbar(mesh, ax=axp, label='capacity along the tether [N]')
    if unsup.any():
        axp.contourf(sx, sy, unsup.astype(float), levels=[0.5, 1.5], colors=['0.75'],
                     alpha=0.5, hatches=['//'])
        axp.fill([], [], color='0.75', hatch='//', label='unsupported')
    gx, gy = np.meshgrid(shown(x, ax[x]), shown(y, ax[y]))
    axp.plot(gx.ravel(), gy.ravel(), 'k.', ms=3, label='grid nodes')
    axp.set_xlabel(f'{x} [{unit[x]}]')
    axp.set_ylabel(f'{y} [{unit[y]}]')
    others = ', '.join(f'{n} {float(shown(n, fixed[n])):.3g} {unit[n]}' for n in g.names
                       if n not in (x, y))
    name = cmap.data.attrs.get('description_name', '')
    axp.set_title(f'{name}, {cmap.medium_name}, {pull} pull, phi {math.degrees(phi):.0f} deg'
                  + (f'; {others}' if others else ''), fontsize=9)
    return save_slice(fig, axp, args.out, cap, unsup)
