"""Fit the medium's two Agarwal parameters (xi_n, mu_surf) to pull tests and plate penetration.

Observations (each a residual in N, divided by its sigma):
  - pull tests: the breakaway force, the largest load-cell reading (5-sample running median)
    before p has moved BREAKAWAY_TRAVEL_M, against the capacity at the test's measured initial
    state (predict.measured_initial_state) for the candidate medium;
  - plate penetration (optional, CSV depth_m,force_N of a horizontal plate of area A pushed
    down): F = 0.875 xi_n A depth (docs/design/models-rft.md), which pins xi_n alone. Each
    --penetration file is a separate test (repeat the option, one file per test); a file with
    a `test` column holds several tests, one per distinct value.
The capacity is nearly linear in xi_n (RFT stress ~ xi_n; the weight is not scaled), and
mu_surf moves it only a few percent, so several leg poses are needed and mu_surf stays the
less certain parameter: the confidence intervals say how much.

Least squares: scipy.optimize.least_squares (trf, bounds) on u = (xi_n / 1e5, mu_surf).
Covariance: s^2 (J^T J)^-1 at the solution, s^2 = chi^2 / dof (the residual scatter sets the
noise level, so sigma only weights the two kinds of data). 95 % intervals: Student t (dof).

    python -m rftgls_ros.lab.calibrate BAG [BAG ...] [--penetration trace.csv ...
        --plate-area A]
        [--method twist-mesh] [--out medium.json] [--name my_sand]
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rftgls_core.rft.media import Medium
from rftgls_core.types import AnchorState

from .bag_layout import BagError, PullTest, read_pull_test
from .evaluate import running_median
from .predict import initial_pose, make_predictor, measured_initial_state

BREAKAWAY_TRAVEL_M = 2e-3
XI_SCALE = 1e5              # N/m^3 per unit of the fitted variable (conditioning)
PLATE_FACTOR = 0.875        # horizontal plate pushed down: stress = 0.875 xi_n per m of depth


@dataclass(frozen=True)
class PullObservation:
    """One pull test reduced to what the fit needs (SI)."""

    test_id: str
    robot: str
    state: AnchorState
    phi: float
    pull: str
    breakaway_N: float

    @classmethod
    def from_test(cls, test: PullTest) -> 'PullObservation':
        if not len(test.tension_N):
            raise ValueError(f'pull test {test.meta.test_id!r}: no /winch/tension samples, no '
                             'breakaway force to fit')
        f = running_median(test.tension_N)
        if len(test.pose):
            dx = initial_pose(test)[0] - np.interp(test.force_t, test.pose_t, test.pose[:, 0])
            f = f[dx <= BREAKAWAY_TRAVEL_M]
        m = test.meta
        return cls(m.test_id, m.robot, measured_initial_state(test), m.phi_rad, m.pull,
                   float(f.max()))


PENETRATION_COLUMNS = ('depth_m', 'force_N')
MAX_PENETRATION_ROWS = 1_000_000


@dataclass(frozen=True)
class PenetrationTrace:
    """One plate-penetration test: depth (m) and force (N) samples, plate area (m^2)."""

    depth_m: np.ndarray
    force_N: np.ndarray
    plate_area_m2: float
    test_id: str = ''

    @classmethod
    def load(cls, path: str | Path, plate_area_m2: float) -> 'PenetrationTrace':
        """A file holding exactly one test (see load_tests)."""
        tests = cls.load_tests(path, plate_area_m2)
        if len(tests) != 1:
            raise ValueError(f'{path}: holds {len(tests)} tests (test column), expected one')
        return tests[0]

    @classmethod
    def load_tests(cls, path: str | Path, plate_area_m2: float) -> list['PenetrationTrace']:
        """CSV with a header naming depth_m and force_N (any order; an optional `test`
        column splits the rows into tests). ValueError (one line, file and line number) on
        a missing column, a non-finite or negative depth, a non-finite force, or < 2 samples
        in a test."""
        if not (isinstance(plate_area_m2, (int, float)) and math.isfinite(plate_area_m2)
                and plate_area_m2 > 0):
            raise ValueError(f'--plate-area must be a positive area in m^2, got {plate_area_m2}')
        try:
            with open(path, newline='') as fh:
                rows = list(csv.reader(fh))
        except UnicodeDecodeError:
            raise ValueError(f'{path}: not a text CSV file') from None
        except csv.Error as exc:
            raise ValueError(f'{path}: malformed CSV ({exc})') from None
        if not rows:
            raise ValueError(f'{path}: empty file; expected a header depth_m,force_N')
        header = [h.strip() for h in rows[0]]
        missing = [c for c in PENETRATION_COLUMNS if c not in header]
        if missing:
            raise ValueError(f'{path}: header {",".join(header)!r} lacks {", ".join(missing)} '
                             f'(columns: depth_m,force_N[,test])')
        if len(rows) - 1 > MAX_PENETRATION_ROWS:
            raise ValueError(f'{path}: more than {MAX_PENETRATION_ROWS} samples')
        i_d, i_f = header.index('depth_m'), header.index('force_N')
        i_t = header.index('test') if 'test' in header else None
        by_test: dict[str, list[tuple[float, float]]] = {}
        for line, row in enumerate(rows[1:], start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise ValueError(f'{path}:{line}: {len(row)} fields, the header has '
                                 f'{len(header)}')
            try:
                depth, force = float(row[i_d]), float(row[i_f])
            except ValueError:
                raise ValueError(f'{path}:{line}: depth_m and force_N must be numbers') from None
            if not (math.isfinite(depth) and math.isfinite(force) and depth >= 0.0):
                raise ValueError(f'{path}:{line}: depth_m must be finite and >= 0 and force_N '
                                 f'finite, got {depth}, {force}')
            key = row[i_t].strip() if i_t is not None else Path(path).stem
            by_test.setdefault(key, []).append((depth, force))
        if not by_test:
            raise ValueError(f'{path}: no samples after the header')
        out = []
        for key, samples in by_test.items():
            if len(samples) < 2:
                raise ValueError(f'{path}: test {key!r} has {len(samples)} sample; at least 2')
            a = np.array(samples, dtype=float)
            out.append(cls(a[:, 0], a[:, 1], float(plate_area_m2), key))
        return out


@dataclass
class Calibration:
    xi_n: float
    mu_surf: float
    cov: np.ndarray              # 2x2, SI: (xi_n N/m^3, mu_surf)
    ci95: dict                   # name -> (low, high)
    dof: int
    residual_rms: dict           # 'pull_N', 'penetration_N'
    n_pull: int
    n_penetration: int
    method: str
    sources: list = field(default_factory=list)
    n_penetration_tests: int = 0

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))

    def medium(self, name: str = 'calibrated') -> Medium:
        return Medium(name, xi_n=self.xi_n, mu_surf=self.mu_surf, zeta=PLATE_FACTOR * self.xi_n,
                      note=f'calibrated ({self.method}) on {self.n_pull} pull tests and '
                           f'{self.n_penetration} penetration samples')

    def to_json(self, name: str = 'calibrated', command: str = '') -> str:
        d = self.medium(name).to_dict()
        d['calibration'] = {
            'covariance': self.cov.tolist(), 'covariance_order': ['xi_n', 'mu_surf'],
            'std': {'xi_n': self.std[0], 'mu_surf': self.std[1]},
            'ci95': {k: list(v) for k, v in self.ci95.items()}, 'dof': self.dof,
            'residual_rms': self.residual_rms, 'n_pull_tests': self.n_pull,
            'n_penetration_samples': self.n_penetration,
            'n_penetration_tests': self.n_penetration_tests, 'surface_method': self.method,
            'sources': self.sources, 'command': command}
        return json.dumps(d, indent=2, allow_nan=False)


def calibrate(pulls: list[PullObservation],
              penetration: PenetrationTrace | list[PenetrationTrace] | None = None,
              method: str = 'twist-mesh', x0: tuple[float, float] = (3.8e5, 0.4),
              sigma_pull_N: float = 0.05, sigma_penetration_N: float = 0.05,
              progress: bool = False) -> Calibration:
    """Least-squares fit. penetration: one test or a list of tests (each its own plate
    area); their samples enter the fit side by side."""
    from scipy import optimize, stats

    from rftgls_core.rft.media import custom_medium

    tests = [] if penetration is None else (
        [penetration] if isinstance(penetration, PenetrationTrace) else list(penetration))
    # One trace of every sample: F = 0.875 xi_n A depth is linear in A * depth, so the
    # tests combine by stacking A * depth next to the forces.
    penetration = None if not tests else PenetrationTrace(
        np.concatenate([t.depth_m * t.plate_area_m2 for t in tests]),
        np.concatenate([t.force_N for t in tests]), 1.0, ','.join(t.test_id for t in tests))
    n_pen = 0 if penetration is None else len(penetration.depth_m)
    if len(pulls) + n_pen < 3:
        raise ValueError('need at least 3 observations for 2 parameters and an error estimate')
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(unit='eval', desc='calibrate', file=sys.stderr)

    def pull_forces(u: np.ndarray) -> np.ndarray:
        med = custom_medium(xi_n=u[0] * XI_SCALE, mu_surf=u[1])
        models = {}
        out = np.empty(len(pulls))
        for i, ob in enumerate(pulls):
            if ob.robot not in models:
                models[ob.robot] = make_predictor(method, ob.robot, med)
            r = models[ob.robot].predict(ob.state, ob.phi, ob.pull)
            # No balance at this medium: the anchor holds nothing; the residual says so
            # (a NaN would stop the solver).
            out[i] = r.capacity_N if r.status.has_value and r.capacity_N is not None else 0.0
        if bar is not None:
            bar.update(1)
        return out

    meas = np.array([ob.breakaway_N for ob in pulls])

    def residuals(u: np.ndarray) -> np.ndarray:
        r = [(pull_forces(u) - meas) / sigma_pull_N] if pulls else []
        if penetration is not None:
            model = PLATE_FACTOR * u[0] * XI_SCALE * penetration.plate_area_m2 * penetration.depth_m
            r.append((model - penetration.force_N) / sigma_penetration_N)
        return np.concatenate(r)

    u0 = np.array([x0[0] / XI_SCALE, x0[1]])
    # diff_step: relative; 1e-3 keeps the finite differences above the solver's round-off
    sol = optimize.least_squares(residuals, u0, bounds=([0.1, 0.0], [100.0, 3.0]),
                                 diff_step=1e-3, x_scale=np.array([1.0, 0.1]), xtol=1e-10,
                                 ftol=1e-10)
    if bar is not None:
        bar.close()
    J = sol.jac
    n = J.shape[0]
    dof = n - 2
    chi2 = float(sol.fun @ sol.fun)
    s2 = chi2 / dof if dof > 0 else 1.0
    cov_u = s2 * np.linalg.pinv(J.T @ J)
    S = np.diag([XI_SCALE, 1.0])
    cov = S @ cov_u @ S
    xi, mu = sol.x[0] * XI_SCALE, sol.x[1]
    t = stats.t.ppf(0.975, max(dof, 1))
    sd = np.sqrt(np.diag(cov))
    rms = {}
    res = sol.fun
    if pulls:
        rms['pull_N'] = float(np.sqrt(np.mean((res[:len(pulls)] * sigma_pull_N) ** 2)))
    if n_pen:
        res_pen = res[len(pulls):] * sigma_penetration_N
        rms['penetration_N'] = float(np.sqrt(np.mean(res_pen ** 2)))
    return Calibration(xi_n=float(xi), mu_surf=float(mu), cov=cov,
                       ci95={'xi_n': (float(xi - t * sd[0]), float(xi + t * sd[0])),
                             'mu_surf': (float(mu - t * sd[1]), float(mu + t * sd[1]))},
                       dof=dof, residual_rms=rms, n_pull=len(pulls), n_penetration=n_pen,
                       method=method, n_penetration_tests=len(tests))


def add_arguments(ap: argparse.ArgumentParser) -> None:
    ap.add_argument('bags', nargs='*', help='pull-test bags')
    ap.add_argument('--penetration', action='append', default=[], metavar='CSV',
                    help='plate-penetration test: CSV with header depth_m,force_N[,test]; '
                         'repeat the option for several tests (each file is its own test)')
    ap.add_argument('--plate-area', type=float, action='append', default=[], metavar='M2',
                    help='penetration plate area, m^2: once for every file, or once per '
                         '--penetration in the same order')
    ap.add_argument('--method', default='twist-mesh',
                    choices=['twist-mesh', 'direct', 'alpha', 'ellipsoid'])
    ap.add_argument('--sigma-pull', type=float, default=0.05, help='N (relative weighting)')
    ap.add_argument('--sigma-penetration', type=float, default=0.05, help='N')
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
    if len(set(map(str, args.bags))) != len(args.bags):
        raise ValueError('a bag is given twice; each pull test counts once')
    if len(set(args.penetration)) != len(args.penetration):
        raise ValueError('a --penetration file is given twice; each test counts once')
    for name in ('sigma_pull', 'sigma_penetration'):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f'--{name.replace("_", "-")} must be a positive number, got {v}')
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
                    sigma_penetration_N=args.sigma_penetration, progress=True)
    cal.sources = [str(b) for b in args.bags] + list(args.penetration)
    Path(args.out).write_text(cal.to_json(args.name, command))
    lo, hi = cal.ci95['xi_n']
    mlo, mhi = cal.ci95['mu_surf']
    print(f'xi_n    = {cal.xi_n:.4g} N/m^3  (95% CI {lo:.4g} .. {hi:.4g})')
    print(f'mu_surf = {cal.mu_surf:.3f}        (95% CI {mlo:.3f} .. {mhi:.3f})')
    print('residual rms: ' + ', '.join(f'{k} {v:.3g}' for k, v in cal.residual_rms.items())
          + f'; dof {cal.dof}; {cal.n_pull} pull test(s), {cal.n_penetration_tests} '
          f'penetration test(s); wrote {args.out}')
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog='python -m rftgls_ros.lab.calibrate',
                                 description='fit (xi_n, mu_surf) with 95%% confidence intervals')
    add_arguments(ap)
    args = ap.parse_args(argv)
    command = 'python -m rftgls_ros.lab.calibrate ' + shlex.join(
        sys.argv[1:] if argv is None else argv)
    try:
        return run(args, command)
    except (ValueError, OSError) as exc:
        print(f'calibrate: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
