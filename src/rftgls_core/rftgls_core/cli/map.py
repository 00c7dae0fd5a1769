"""`rftgls map`: build, inspect and check precomputed capacity maps (HDF5, see maps/hdf5.py).

    rftgls map build --robot NAME --medium NAME --out FILE.h5 [grid options] [--workers N]
                     [--scheduler ADDRESS]
    rftgls map info FILE [--json]
    rftgls map accuracy FILE [--samples N] [--reference direct] [--json]
    rftgls map refine FILE --out NEW.h5 [--tol PCT] [--samples N]
    rftgls map plot FILE --x AXIS --y AXIS --out SLICE.png  (see cli/map_plot.py)
A described map (`map build --anchor`) takes the same actions; accuracy and refine need
--anchor FILE.yaml (cli/map_described.py).

Grid options take mm (h) and degrees (angles) as 'start:step:stop' (inclusive) or 'a,b,c';
write negative values with '=' (--theta-l1=-40:20:40). Missing axes come from the robot's
default grid (maps/grid.py).
"""
from __future__ import annotations

import math
import os
import shlex

import numpy as np

from rftgls_conventions.safe_write import output_file

from ..quantities import (
    ANGLE_DEG,
    PERCENT,
    POSITION_MM,
    SEED,
    TETHER_PHI_DEG,
    WORKERS,
    Quantity,
    bounded_int,
)
from ..robots.presets import ROBOTS
from ..surfaces.registry import DEFAULT_METHOD, DEFAULT_TWISTS, METHOD_NAMES
from .common import add_medium_args, medium_from_args, print_json, twist_count

MAP_SUFFIXES = ('.h5', '.hdf5')
GRID_QUANTITY: dict[str, Quantity] = {'h': POSITION_MM, 'theta_b': ANGLE_DEG,
                                      'theta_l1': ANGLE_DEG, 'theta_l2': ANGLE_DEG,
                                      'phi': TETHER_PHI_DEG}
GRID_FLAGS = (('h', 'h_mm', 'MM'), ('theta_b', 'theta_b_deg', 'DEG'),
              ('theta_l1', 'theta_l1_deg', 'DEG'), ('theta_l2', 'theta_l2_deg', 'DEG'),
              ('phi', 'phi_deg', 'DEG'))


def add_parser(sub) -> None:
    p = sub.add_parser('map', help='build / inspect precomputed capacity maps',
                       description='State-space maps of load capacity and slip twist over '
                       '(h, thetaB, thetaL1, thetaL2) and pull angles (HDF5).')
    msub = p.add_subparsers(dest='map_command', required=True, metavar='ACTION')

    b = msub.add_parser('build', help='compute a map and write it to an HDF5 file')
    who = b.add_mutually_exclusive_group(required=True)
    who.add_argument('--robot', choices=sorted(ROBOTS))
    who.add_argument('--anchor', metavar='FILE.yaml',
                     help='anchor description: a map over ITS state variables (their map '
                          'ranges; --axis NAME=RANGE replaces one, in the YAML\'s unit)')
    b.add_argument('--axis', action='append', default=[], metavar='NAME=RANGE',
                   help='with --anchor: nodes of a state variable, start:step:stop or a,b,c in '
                        'its unit (may repeat)')
    add_medium_args(b)
    b.add_argument('--method', default=DEFAULT_METHOD, choices=sorted(METHOD_NAMES),
                   help='limit-surface method (default: %(default)s)')
    b.add_argument('--n-twists', type=twist_count, default=DEFAULT_TWISTS,
                   help='twists sampled per state (default: %(default)s)')
    b.add_argument('--out', required=True, help='output .h5 file (overwritten)')
    g = b.add_argument_group('grid (mm and degrees; default: the robot\'s grid)')
    g.add_argument('--h', dest='h_mm', metavar='MM', help="winch-point height, e.g. 5:5:30")
    g.add_argument('--theta-b', dest='theta_b_deg', metavar='DEG',
                   help='body pitch, e.g. -20:10:20')
    g.add_argument('--theta-l1', dest='theta_l1_deg', metavar='DEG', help='proximal leg angle')
    g.add_argument('--theta-l2', dest='theta_l2_deg', metavar='DEG', help='distal leg angle')
    g.add_argument('--phi', dest='phi_deg', metavar='DEG',
                   help='pull angles (default -30:10:10)')
    g.add_argument('--pulls', default='forward,backward',
                   help='pull orientations, comma separated (default: %(default)s)')
    r = b.add_argument_group('execution (does not change the result)')
    r.add_argument('--workers', type=WORKERS, default=None,
                   help='local worker processes (default: all cores; 1 = no pool)')
    r.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='Dask distributed scheduler, e.g. tcp://127.0.0.1:8786')
    r.add_argument('--quiet', action='store_true', help='no progress bar')
    b.set_defaults(run=run_build)

    i = msub.add_parser('info', help='print the schema summary of a map file')
    i.add_argument('file')
    i.add_argument('--json', action='store_true', help='print JSON')
    i.set_defaults(run=run_info)

    a = msub.add_parser('accuracy', help='map vs. the direct method between nodes')
    a.add_argument('file')
    a.add_argument('--samples', type=bounded_int(1, 10_000, 'sample count'), default=20,
                   help='cell centres and as many random states (default: %(default)s)')
    a.add_argument('--reference', default='direct', choices=sorted(METHOD_NAMES),
                   help='reference method (default: %(default)s)')
    a.add_argument('--seed', type=SEED, default=0)
    a.add_argument('--support-edge', action='store_true',
                   help='query with the opt-in support-edge rule (maps/README.md)')
    a.add_argument('--random', type=bounded_int(0, 100_000, 'state count'), default=0,
                   metavar='N',
                   help='instead: coverage and overestimate against the live reference at N '
                        'random states of the robot (both pulls, phi -30..10 deg)')
    a.add_argument('--json', action='store_true', help='print JSON')
    a.add_argument('--quiet', action='store_true', help='no progress bar')
    a.add_argument('--anchor', metavar='FILE.yaml', help='a described map\'s description')
    a.set_defaults(run=run_accuracy)


    f = msub.add_parser('refine', help='add grid nodes where the map error exceeds a tolerance')
    f.add_argument('file')
    f.add_argument('--out', required=True, help='refined map (.h5)')
    f.add_argument('--tol', type=PERCENT.arg, default=5.0,
                   help='p95 capacity error per axis interval, %% (default: %(default)s)')
    f.add_argument('--samples', type=bounded_int(1, 1000, 'sample count'), default=6,
                   help='states per interval')
    f.add_argument('--seed', type=SEED, default=0)
    f.add_argument('--workers', type=WORKERS, default=None)
    f.add_argument('--dry-run', action='store_true', help='report intervals, build nothing')
    f.add_argument('--quiet', action='store_true', help='no progress bar')
    f.add_argument('--anchor', metavar='FILE.yaml', help='a described map\'s description')
    f.set_defaults(run=run_refine)

    from .map_plot import add_plot_parser  # `rftgls map plot` (heatmap slices), cli/map_plot.py
    add_plot_parser(msub)


def grid_from_args(args):
    """The robot's default grid with the axes given on the command line replaced."""
    from ..maps.grid import MapGrid, default_grid, parse_range
    base = default_grid(args.robot)
    given = {a: parse_range(getattr(args, d)) for a, d, _ in GRID_FLAGS
             if getattr(args, d) is not None}
    for a, values in given.items():
        q = GRID_QUANTITY[a]
        for v in values:
            q.check(v, f'--{a.replace("_", "-")}')
    # mm and degrees -> SI only for the given axes; default axes stay bit-exact.
    conv = {a: (v * 1e-3 if a == 'h' else np.radians(v)) for a, v in given.items()}
    pulls = tuple(p.strip() for p in args.pulls.split(',') if p.strip())
    return MapGrid(**{a: conv.get(a, getattr(base, a)) for a, _, _ in GRID_FLAGS}, pulls=pulls)


def canonical_command(args, medium_name: str) -> str:
    """A command line that rebuilds the same contents (execution options and --out left out)."""
    parts = ['rftgls', 'map', 'build', '--robot', args.robot]
    if args.xi_n is not None or args.mu_surf is not None or args.zeta is not None:
        for flag, v in (('--xi-n', args.xi_n), ('--mu-surf', args.mu_surf), ('--zeta', args.zeta)):
            if v is not None:
                parts += [flag, repr(v)]
    else:
        parts += ['--medium', medium_name]
    parts += ['--model', args.model, '--method', args.method, '--n-twists', str(args.n_twists)]
    for axis, dest, _ in GRID_FLAGS:
        if getattr(args, dest) is not None:
            # '=' form: values like -40:20:40 would otherwise parse as options.
            parts += [f'--{axis.replace("_", "-")}={getattr(args, dest)}']
    if args.pulls != 'forward,backward':
        parts += ['--pulls', args.pulls]
    return shlex.join(parts)


def run_build_anchor(args) -> int:
    """`map build --anchor`: a described map (maps/described.py) over the description's state
    variables, built in this process."""
    from ..description import load_description
    from ..maps.described import description_grid, save_described_map
    from ..maps.described_build import build_described_map
    from ..maps.grid import DEFAULT_PHI_DEG, parse_range
    from .map_described import local_workers
    if args.scheduler:
        raise ValueError('--anchor maps are built by local workers: drop --scheduler')
    if any(getattr(args, d) is not None for a, d, _ in GRID_FLAGS if a != 'phi'):
        raise ValueError('--anchor takes its state axes by --axis NAME=RANGE (the robot axes '
                         '--h/--theta-* belong to --robot)')
    desc = load_description(args.anchor)
    args.default_medium = desc.medium
    medium = medium_from_args(args)
    overrides = {}
    for item in args.axis:
        name, sep, text = item.partition('=')
        if not sep:
            raise ValueError(f'--axis wants NAME=RANGE, got {item!r}')
        overrides[name.strip()] = parse_range(text)
    phi = parse_range(args.phi_deg) if args.phi_deg is not None else DEFAULT_PHI_DEG
    pulls = None if args.pulls == 'forward,backward' else tuple(
        p.strip() for p in args.pulls.split(',') if p.strip())
    for v in desc.state:
        lo, hi = v.physical
        for x in overrides.get(v.name, ()):
            if not lo <= v.to_si(x) <= hi:
                raise ValueError(f'--axis {v.name}: {x:g} {v.unit} lies outside its physical '
                                 f'range in {args.anchor}')
    for x in phi:
        TETHER_PHI_DEG.check(x, '--phi')
    grid = description_grid(desc, overrides, phi, pulls)
    out = os.fspath(args.out)
    if args.n_twists < 8:
        raise ValueError(f'--n-twists must be >= 8, got {args.n_twists}')
    # As for robot maps: --n-twists (default DEFAULT_TWISTS) for every method.
    data = build_described_map(desc, medium, grid, method=args.method, model=args.model,
                               n_twists=args.n_twists, progress=not args.quiet,
                               command=_anchor_command(args, medium.name),
                               workers=local_workers(args.workers))
    path = save_described_map(out, data)
    codes = np.bincount(data.status.reshape(-1))
    from ..maps.hdf5 import STATUS_NAMES
    counts = ', '.join(f'{STATUS_NAMES[i]} {int(c)}' for i, c in enumerate(codes) if c)
    print(f'{path}: {desc.name} ({desc.sha256[:12]}): {grid.describe()}; answers: {counts}')
    return 0


def _anchor_command(args, medium_name: str) -> str:
    """The command line that rebuilds an --anchor map (execution options and --out left out)."""
    parts = ['rftgls', 'map', 'build', '--anchor', str(args.anchor), '--medium', medium_name,
             '--model', args.model, '--method', args.method, '--n-twists', str(args.n_twists)]
    parts += [f'--axis={a}' for a in args.axis]
    if args.phi_deg is not None:
        parts.append(f'--phi={args.phi_deg}')
    if args.pulls != 'forward,backward':
        parts += ['--pulls', args.pulls]
    return shlex.join(parts)


def run_build(args) -> int:
    output_file(args.out, '--out', MAP_SUFFIXES)   # checked before any work
    if args.scheduler:
        from ..maps.build import probe_scheduler
        probe_scheduler(args.scheduler)
    if args.anchor is not None:
        return run_build_anchor(args)
    if args.axis:
        raise ValueError('--axis belongs to --anchor; --robot takes --h/--theta-b/...')
    from ..maps.build import build_map, status_counts
    from ..maps.hdf5 import save_map
    medium = medium_from_args(args)
    if args.n_twists < 8:
        raise ValueError(f'--n-twists must be >= 8, got {args.n_twists}')
    grid = grid_from_args(args)
    out = os.fspath(args.out)
    data = build_map(args.robot, medium, grid, method=args.method, model=args.model,
                     n_twists=args.n_twists, workers=args.workers, scheduler=args.scheduler,
                     progress=not args.quiet, command=canonical_command(args, medium.name))
    path = save_map(out, data)
    counts = ', '.join(f'{k} {v}' for k, v in status_counts(data).items())
    print(f'{path}: {grid.describe()}; answers: {counts}; {path.stat().st_size / 1e3:.0f} kB')
    return 0


def info_dict(path: str) -> dict:
    from ..maps.build import status_counts
    from ..maps.grid import AXIS_HUMAN, AXIS_UNITS
    from ..maps.hdf5 import SCHEMA, SCHEMA_VERSION, load_map
    from ..maps.shipped import resolve_map
    path = str(resolve_map(path))
    data = load_map(path)
    g = data.grid
    axes = {}
    for name in ('h', 'theta_b', 'theta_l1', 'theta_l2', 'phi'):
        unit, f = AXIS_HUMAN[name]
        v = getattr(g, name)
        axes[name] = {'n': int(len(v)), 'units': AXIS_UNITS[name], 'min': float(v[0]),
                      'max': float(v[-1]), f'values_{unit}': [round(float(x) * f, 6) for x in v]}
    prov = data.provenance
    return {'file': str(path), 'size_bytes': os.path.getsize(path), 'schema': SCHEMA,
            'schema_version': SCHEMA_VERSION if data.support_margin is not None else 1,
            'robot': data.attrs['robot'],
            'medium': data.attrs['medium'], 'method': data.attrs['method'],
            'rft_model': data.attrs['rft_model'], 'n_twists': data.attrs['n_twists'],
            'scaling': {'force_N': data.attrs['scaling_force_N'],
                        'length_m': data.attrs['scaling_length_m']},
            'pulls': list(g.pulls), 'axes': axes, 'n_states': g.n_states,
            'shape': list(g.shape), 'status_counts': status_counts(data),
            'reasons': [r for r in data.reason_names if r],
            'package_version': data.attrs['package_version'],
            'build_command': data.attrs['build_command'],
            'build_time_utc': data.attrs.get('build_time_utc', ''),
            'integrity': data.integrity, 'content_sha256': _stored_hash(path),
            'robot_params': prov.get('robot', {}), 'medium_params': prov.get('medium', {})}


def _stored_hash(path: str) -> str | None:
    import h5py

    from ..maps.hdf5 import HASH_ATTR
    with h5py.File(path, 'r') as f:
        value = f.attrs.get(HASH_ATTR)
    return None if value is None else str(value)


def described_info(path: str) -> dict:
    """`map info` of a described map (maps/described.py)."""
    from ..maps.described import load_described_map
    from ..maps.hdf5 import STATUS_NAMES
    data = load_described_map(path)
    g = data.grid
    axes = {}
    for n, u, a in zip(g.names, g.units, g.axes):
        f = 180.0 / math.pi if u == 'deg' else 1.0
        axes[n] = {'n': len(a), 'units': 'rad' if u == 'deg' else 'm', 'min': float(a[0]),
                   'max': float(a[-1]), f'values_{u}': [round(float(x) * f, 6) for x in a]}
    axes['phi'] = {'n': len(g.phi), 'units': 'rad', 'min': float(g.phi[0]),
                   'max': float(g.phi[-1]),
                   'values_deg': [round(math.degrees(float(x)), 6) for x in g.phi]}
    counts = np.bincount(data.status.reshape(-1), minlength=len(STATUS_NAMES))
    at = data.attrs
    return {'file': str(path), 'size_bytes': os.path.getsize(path), 'schema': at['schema'],
            'schema_version': at['schema_version'], 'description': at['description_name'],
            'description_sha256': at['description_sha256'], 'medium': at['medium'],
            'method': at['method'], 'rft_model': at['rft_model'], 'n_twists': at['n_twists'],
            'space': at['space'], 'pulls': list(g.pulls), 'axes': axes,
            'n_states': g.n_states, 'shape': list(g.shape),
            'status_counts': {STATUS_NAMES[i]: int(c) for i, c in enumerate(counts) if c},
            'reasons': [r for r in data.reason_names if r],
            'package_version': at['package_version'], 'build_command': at['build_command'],
            'build_time_utc': at.get('build_time_utc', ''), 'integrity': 'verified',
            'content_sha256': at['content_sha256']}


def run_info(args) -> int:
    from ..maps.described import is_described_map
    if is_described_map(args.file):
        info = described_info(args.file)
        if args.json:
            print_json(info)
            return 0
        print(f"{info['file']}: {info['schema']} v{info['schema_version']}, description "
              f"{info['description']} ({info['description_sha256'][:12]}), medium "
              f"{info['medium']}, method {info['method']}, space {info['space']}")
        for name, ax in info['axes'].items():
            human = next(k for k in ax if k.startswith('values_'))
            print(f"  {name:9s} [{ax['units']}] {ax['n']:2d} nodes: "
                  + ' '.join(f'{v:g}' for v in ax[human]) + f' {human[7:]}')
        print(f"pulls {', '.join(info['pulls'])}; {info['n_states']} states; answers: "
              + ', '.join(f'{k} {v}' for k, v in info['status_counts'].items()))
        print(f"built {info['build_time_utc']}: {info['build_command']}; integrity verified "
              f"(content_sha256 {info['content_sha256']})")
        return 0
    info = info_dict(args.file)
    if args.json:
        print_json(info)
        return 0
    print(f"{info['file']}: {info['schema']} v{info['schema_version']}, "
          f"{info['size_bytes'] / 1e3:.0f} kB")
    print(f"robot {info['robot']}, medium {info['medium']}, RFT {info['rft_model']}, "
          f"method {info['method']}, {info['n_twists']} twists, scaling s_F "
          f"{info['scaling']['force_N']:.4g} N, L_c {info['scaling']['length_m']:.4g} m")
    for name, ax in info['axes'].items():
        human = next(k for k in ax if k.startswith('values_'))
        vals = ' '.join(f'{v:g}' for v in ax[human])
        print(f"  {name:9s} [{ax['units']}] {ax['n']:2d} nodes: {vals} {human[7:]}")
    print(f"pulls {', '.join(info['pulls'])}; {info['n_states']} states; array shape "
          f"{tuple(info['shape'])} (pull, h, theta_b, theta_l1, theta_l2, phi)")
    print('answers: ' + ', '.join(f'{k} {v}' for k, v in info['status_counts'].items())
          + (f"; reasons: {', '.join(info['reasons'])}" if info['reasons'] else ''))
    print(f"built {info['build_time_utc']} by rftgls_core {info['package_version']}: "
          f"{info['build_command']}")
    sha = info['content_sha256']
    print(f"integrity {info['integrity']}" + (f" (content_sha256 {sha})" if sha else ''))
    return 0


def run_accuracy(args) -> int:
    from ..maps.accuracy import accuracy_report
    from ..maps.query import CapacityMap
    from ..maps.shipped import resolve_map
    if args.samples < 1:
        raise ValueError(f'--samples must be >= 1, got {args.samples}')
    if args.random < 0:
        raise ValueError(f'--random must be >= 0, got {args.random}')
    from ..maps.described import is_described_map
    described = None
    if is_described_map(args.file):
        from .map_described import accuracy as described_accuracy
        described = described_accuracy(args)
    elif args.anchor:
        raise ValueError('--anchor is for described maps (`map build --anchor`)')
    if args.random and described is None:
        from ..maps.accuracy import coverage_report
        cov = coverage_report(CapacityMap.load(resolve_map(args.file),
                                               support_edge=args.support_edge),
                              n=args.random, seed=args.seed, reference=args.reference,
                              progress=not args.quiet)
        if args.json:
            d = cov.to_dict()
            d.update({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                      for k, v in d.items()})
            print_json(d)
            return 0
        print(f'{args.file} vs live {cov.reference}: {cov.n_states} random states, reference '
              f'answers {cov.ref_answers}, map answers {cov.map_answers} of them '
              f'({cov.coverage_pct:.1f} %), map-only answers {cov.map_only}')
        print(f'  largest overestimate {cov.over_N_worst:+.3f} N where both answer, '
              f'{cov.map_only_N_worst:.3f} N where the live solver holds nothing (unsupported),'
              f' so {cov.over_all_N_worst:+.3f} N over all states')
        print(f'  |error| p95 '
              f'{cov.err_N_p95:.3f} N; map answers by rule: '
              + ', '.join(f'{k or "interior"} {v}' for k, v in sorted(cov.by_flag.items())))
        return 0
    rep = described or accuracy_report(CapacityMap.load(resolve_map(args.file),
                                                        support_edge=args.support_edge),
                                       samples=args.samples, seed=args.seed,
                                       reference=args.reference, progress=not args.quiet)
    if args.json:
        d = rep.to_dict()
        if not math.isfinite(d['capacity_over_N_worst']):
            d['capacity_over_N_worst'] = None
        for k in ('capacity_N', 'capacity_pct', 'twist_deg'):
            d[k] = {kk: (None if not math.isfinite(v) else v) for kk, v in d[k].items()}
        print_json(d)
        return 0
    print(f'{args.file} vs {rep.reference}: {rep.n_states} states, {rep.n_compared} answers '
          f'compared, {rep.status_mismatch} status mismatches '
          f'({rep.map_conservative} where only the reference has a value)')
    for label, s in (('capacity error [N]', rep.capacity_N), ('capacity error [%]',
                     rep.capacity_pct), ('slip-twist angle [deg]', rep.twist_deg)):
        print(f'  {label:24s} mean {s.mean:8.3g}   p95 {s.p95:8.3g}   worst {s.worst:8.3g}')
    print(f'  largest overestimate     {rep.capacity_over_N_worst:+.3g} N (map above the '
          'reference)')
    if rep.note:
        print(f'note: {rep.note}')
    return 0



def run_refine(args) -> int:
    from ..maps.build import build_map, spec_from_map
    from ..maps.described import is_described_map
    from ..maps.grid import AXIS_HUMAN
    from ..maps.hdf5 import save_map
    from ..maps.query import CapacityMap
    from ..maps.refine import interval_errors, refined_grid
    from ..maps.shipped import resolve_map
    output_file(args.out, '--out', MAP_SUFFIXES)   # checked before any work
    if is_described_map(args.file):
        from .map_described import refine as described_refine
        return described_refine(args)
    if args.anchor:
        raise ValueError('--anchor is for described maps (`map build --anchor`)')
    cmap = CapacityMap.load(resolve_map(args.file))
    errors = interval_errors(cmap, samples=args.samples, seed=args.seed,
                             progress=not args.quiet)
    grid = refined_grid(cmap.grid, errors, args.tol)
    for e in errors:
        unit, fac = AXIS_HUMAN[e.axis]
        flag = '  <- refine' if math.isfinite(e.p95_pct) and e.p95_pct > args.tol else ''
        print(f'{e.axis:9s} {e.lo * fac:7.2f} .. {e.hi * fac:7.2f} {unit:3s}  p95 '
              f'{e.p95_pct:6.2f} %  ({e.compared} compared, {e.mismatched} status differ){flag}')
    added = grid.n_states - cmap.grid.n_states
    print(f'{cmap.grid.n_states} -> {grid.n_states} states (+{added})')
    if args.dry_run or added == 0:
        return 0
    spec = spec_from_map(cmap.data)
    parts = [f'rftgls map build --robot {spec.robot} --medium {spec.medium.name} --method '
             f'{spec.method} --n-twists {spec.n_twists}']
    for axis in ('h', 'theta_b', 'theta_l1', 'theta_l2', 'phi'):
        unit, fac = AXIS_HUMAN[axis]
        vals = ','.join(f'{v * fac:.6g}' for v in getattr(grid, axis))
        parts.append(f'--{axis.replace("_", "-")}={vals}')
    data = build_map(spec.robot, spec.medium, grid, method=spec.method, model=spec.model,
                     n_twists=spec.n_twists, workers=args.workers, progress=not args.quiet,
                     command=' '.join(parts))
    print(f'wrote {save_map(args.out, data)}')
    return 0
