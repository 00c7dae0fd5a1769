"""`rftgls calibrate` / rftgls_lab_calibrate: fit the medium's (xi_n, mu_surf) to pull tests and
plate penetration, write a medium file the other commands accept (--medium) and its fit plot
next to it (medium.json -> medium_fit.png). The fit itself: lab/calibration.py.

    python -m rftgls_ros.lab.calibrate BAG [BAG ...] [--penetration trace.csv ...
        --plate-area A]
        [--method twist-mesh] [--out medium.json] [--name my_sand]
"""
from __future__ import annotations

import argparse
import math
import shlex
import sys

from rftgls_conventions.safe_write import output_file, write_text
from rftgls_core.charts.figure_io import figure_path
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.quantities import FORCE_SIGMA_N, PLATE_AREA_M2
from rftgls_node_base.node_main import program_args

from .bag_layout import BagError, read_pull_test
from .calibration import PenetrationTrace, PullObservation, calibrate
from .calibration_plot import plot_fit, plot_path
from .predict import (
    add_anchor_arguments,
    load_anchor,
)


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument('bags', nargs='*', help='pull-test bags')
    ap.add_argument('--penetration', action='append', default=[], metavar='CSV',
                    help='plate-penetration test: CSV with header depth_m,force_N[,test]; '
                         'repeat the option for several tests (each file is its own test)')
    ap.add_argument('--plate-area', type=PLATE_AREA_M2.arg, action='append', default=[],
                    metavar='M2',
                    help='penetration plate area, m^2: once for every file, or once per '
                         '--penetration in the same order')
    ap.add_argument('--method', default='twist-mesh',
                    choices=['twist-mesh', 'direct', 'alpha', 'ellipsoid'])
    add_anchor_arguments(ap)
    ap.add_argument('--sigma-pull', type=FORCE_SIGMA_N.arg, default=0.05,
                    help='N (relative weighting)')
    ap.add_argument('--sigma-penetration', type=FORCE_SIGMA_N.arg, default=0.05, help='N')
    ap.add_argument('--name', default='calibrated')
    ap.add_argument('--out', default='medium_calibrated.json')


def add_parser(sub) -> None:
    """`rftgls calibrate` (registered through the rftgls.commands entry point)."""
    ap = sub.add_parser('calibrate', help='fit the medium (xi_n, mu_surf) to pull-test bags',
                        description='fit (xi_n, mu_surf) with 95%% confidence intervals and '
                                    'write a medium file the other commands accept (--medium)')
    add_arguments(ap)
    ap.set_defaults(run=lambda args: run(args, 'rftgls calibrate ' + shlex.join(sys.argv[2:])))


def run(args, command: str) -> int:
    """Errors propagate as ValueError/OSError (the rftgls CLI prints them in one line)."""
    out = output_file(args.out, '--out', ('.json',))    # both outputs checked before work
    png = figure_path(plot_path(out), '--out (its plot)')
    if len(set(map(str, args.bags))) != len(args.bags):
        raise ValueError('a bag is given twice; each pull test counts once')
    if len(set(args.penetration)) != len(args.penetration):
        raise ValueError('a --penetration file is given twice; each test counts once')
    for name in ('sigma_pull', 'sigma_penetration'):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f'--{name.replace("_", "-")} must be a positive number, got {v}')
    anchor = load_anchor(args.anchor, args.anchor_state)
    pulls = []
    for bag in args.bags:
        try:
            pulls.append(PullObservation.from_test(read_pull_test(bag)))
        except BagError:
            raise
        except ValueError as exc:
            raise ValueError(f'{bag}: {exc}') from None
    pen = []
    if args.penetration:
        areas = args.plate_area
        if len(areas) not in (1, len(args.penetration)):
            raise ValueError(f'give --plate-area once, or once per --penetration '
                             f'({len(args.penetration)}), not {len(areas)} times')
        if len(areas) == 1:
            areas = areas * len(args.penetration)
        for path, area in zip(args.penetration, areas):
            pen += PenetrationTrace.load_tests(path, area)
    elif args.plate_area:
        raise ValueError('--plate-area is used only with --penetration')
    cal = calibrate(pulls, pen or None, method=args.method, sigma_pull_N=args.sigma_pull,
                    sigma_penetration_N=args.sigma_penetration, progress=True, anchor=anchor)
    cal.sources = [str(b) for b in args.bags] + list(args.penetration)
    write_text(out, cal.to_json(args.name, command))
    plot_fit(cal, png)
    lo, hi = cal.ci95['xi_n']
    print(f'xi_n    = {cal.xi_n:.4g} N/m^3  (95% CI {lo:.4g} .. {hi:.4g}, '
          f'{cal.interval_basis["xi_n"]})')
    if cal.ci95['mu_surf'] is None:
        print(f'mu_surf = {cal.mu_surf:.3f}        {cal.fixed["mu_surf"]} (no interval)')
    else:
        mlo, mhi = cal.ci95['mu_surf']
        print(f'mu_surf = {cal.mu_surf:.3f}        (95% CI {mlo:.3f} .. {mhi:.3f})')
    if cal.test_scatter:
        print(f'between penetration tests: xi_n scatters by '
              f'{100 * cal.test_scatter["xi_n_rel_sd"]:.1f} % (1 sd)')
    print('residual rms: ' + ', '.join(f'{k} {v:.3g}' for k, v in cal.residual_rms.items())
          + f'; dof {cal.dof}; {cal.n_pull} pull test(s), {cal.n_penetration_tests} '
          f'penetration test(s); wrote {args.out} and {png}')
    return 0


@cli_contract('calibrate')
def main(argv: list[str] | None = None) -> int:
    ap = RftglsParser(prog='python -m rftgls_ros.lab.calibrate',
                                 description='fit (xi_n, mu_surf) with 95%% confidence intervals')
    add_arguments(ap)
    args = ap.parse_args(program_args(argv, ap.prog))
    command = 'python -m rftgls_ros.lab.calibrate ' + shlex.join(
        sys.argv[1:] if argv is None else argv)
    try:
        return run(args, command)
    except (ValueError, OSError) as exc:
        print(f'calibrate: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
