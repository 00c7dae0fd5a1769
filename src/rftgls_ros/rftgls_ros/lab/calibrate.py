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

Least squares: scipy.optimize.least_squares (trf, bounds) on u = (xi_n / 1e5, log mu_surf):
friction cannot go negative, its interval is exp of a symmetric one in log mu_surf.
Uncertainty (docs/design/calibration.md): every pull test and every penetration test is a
separate experiment. With more tests than fitted parameters the covariance is cluster-robust
over tests (the scatter BETWEEN tests, not the residuals within one), per parameter never
narrower than the pooled residual scatter s^2 (J^T J)^-1; with fewer tests only the latter
('within_test'). 95 %
intervals: Student t with (tests - fitted parameters) dof. A parameter the data do not
identify (mu_surf without pull tests) is fixed at its start value: no interval, null in the
medium file's calibration.ci95, its reason in calibration.fixed.
A fit/residual plot is written next to the output (medium.json -> medium_fit.png).

    python -m rftgls_ros.lab.calibrate BAG [BAG ...] [--penetration trace.csv ...
        --plate-area A]
        [--method twist-mesh] [--out medium.json] [--name my_sand]
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import math
import shlex
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rftgls_conventions.safe_read import read_text
from rftgls_conventions.safe_write import output_file, write_text
from rftgls_core.charts.figure_io import figure_path, pyplot, save
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.predictor import Predictor
from rftgls_core.quantities import FORCE_SIGMA_N, PLATE_AREA_M2
from rftgls_core.rft.media import Medium
from rftgls_core.types import AnchorState
from rftgls_node_base.node_main import program_args

from .bag_layout import BagError, PullTest, read_pull_test
from .evaluate import running_median
from .predict import (
    LabAnchor,
    add_anchor_arguments,
    initial_pose,
    load_anchor,
    make_predictor,
    measured_initial_state,
)

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
            rows = list(csv.reader(io.StringIO(read_text(path, 'csv', 'penetration CSV'),
                                               newline='')))
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


PARAMS = ('xi_n', 'mu_surf')


@dataclass
class Calibration:
    """Fitted medium parameters (SI) and how well the data pin them.

    cov: 2x2 covariance over (xi_n N/m^3, mu_surf); the row and column of a parameter that
    was not fitted are 0 (it is fixed, see `fixed`). ci95: name -> (low, high), or None for a
    fixed parameter. interval_basis: per fitted parameter 'between_tests' (cluster-robust over
    separate tests) or 'within_test' (pooled residual scatter: one test, or wider than the
    between-test estimate).
    """

    xi_n: float
    mu_surf: float
    cov: np.ndarray              # 2x2, SI: (xi_n N/m^3, mu_surf)
    ci95: dict                   # name -> (low, high) | None (not identified, fixed)
    dof: int
    residual_rms: dict           # 'pull_N', 'penetration_N'
    n_pull: int
    n_penetration: int
    method: str
    sources: list = field(default_factory=list)
    n_penetration_tests: int = 0
    fixed: dict = field(default_factory=dict)        # name -> why it was not fitted
    interval_basis: dict = field(default_factory=dict)   # fitted name -> basis
    n_tests: int = 0                                  # independent experiments (clusters)
    test_scatter: dict = field(default_factory=dict)  # 'xi_n_rel_sd' between penetration tests
    # What the fit/residual plot needs: per penetration test (id, A*depth m^3, force N), and
    # per pull test (id, measured N, predicted N).
    penetration_tests: list = field(default_factory=list)
    pull_fit: list = field(default_factory=list)

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))

    def medium(self, name: str = 'calibrated') -> Medium:
        return Medium(name, xi_n=self.xi_n, mu_surf=self.mu_surf, zeta=PLATE_FACTOR * self.xi_n,
                      note=f'calibrated ({self.method}) on {self.n_pull} pull tests and '
                           f'{self.n_penetration} penetration samples'
                           + ''.join(f'; {k} fixed ({v})' for k, v in self.fixed.items()))

    def to_json(self, name: str = 'calibrated', command: str = '') -> str:
        d = self.medium(name).to_dict()
        std = {k: (None if k in self.fixed else float(s)) for k, s in zip(PARAMS, self.std)}
        d['calibration'] = {
            'covariance': self.cov.tolist(), 'covariance_order': list(PARAMS),
            'std': std,
            'ci95': {k: (None if v is None else list(v)) for k, v in self.ci95.items()},
            'fixed': self.fixed, 'interval_basis': self.interval_basis,
            'n_tests': self.n_tests, 'test_scatter': self.test_scatter, 'dof': self.dof,
            'residual_rms': self.residual_rms, 'n_pull_tests': self.n_pull,
            'n_penetration_samples': self.n_penetration,
            'n_penetration_tests': self.n_penetration_tests, 'surface_method': self.method,
            'sources': self.sources, 'command': command}
        return json.dumps(d, indent=2, allow_nan=False)


MU_BOUNDS = (1e-3, 3.0)      # friction coefficient range of the fit (log parametrisation)
IDENTIFIED_REL = 1e-6        # a Jacobian column below this share of the largest: not identified


def _cluster_covariance(J: np.ndarray, r: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Cluster-robust (CR1) covariance of least-squares parameters, clusters = tests.

    (J^T J)^-1 (sum_g J_g^T r_g r_g^T J_g) (J^T J)^-1 * G/(G-1): the spread of the per-test
    score contributions, so tests that disagree widen the interval however many samples each
    test holds (for plate penetration alone it reduces to s_between^2 / G of the per-test
    xi_n estimates).
    """
    bread = np.linalg.pinv(J.T @ J)
    meat = np.zeros((J.shape[1], J.shape[1]))
    labels = np.unique(groups)
    for g in labels:
        sg = J[groups == g].T @ r[groups == g]
        meat += np.outer(sg, sg)
    G = len(labels)
    return bread @ meat @ bread * (G / (G - 1))


def calibrate(pulls: list[PullObservation],
              penetration: PenetrationTrace | list[PenetrationTrace] | None = None,
              method: str = 'twist-mesh', x0: tuple[float, float] = (3.8e5, 0.4),
              sigma_pull_N: float = 0.05, sigma_penetration_N: float = 0.05,
              progress: bool = False, anchor: LabAnchor | None = None) -> Calibration:
    """Least-squares fit of (xi_n, mu_surf) to pull tests and penetration tests.

    anchor: the description posed for every pull test (None: each test's own robot preset).
    penetration: one test or a list of tests (each its own plate area). Every penetration
    test and every pull test is a separate experiment (a cluster): with more tests than
    fitted parameters, each parameter's standard deviation is the wider of the cluster-robust
    one over tests (`_cluster_covariance`) and the pooled residual one (s^2 (J^T J)^-1), with
    Student t on tests - fitted parameters dof; otherwise only the residual scatter is known.
    Parameters: u = (xi_n / XI_SCALE, log mu_surf), so friction cannot go negative and its
    interval is exp of a symmetric one. mu_surf enters only the pull tests: without them it is
    not identified and stays fixed at x0[1] (no interval, `fixed`); the same happens when
    the pull capacities do not move with it (a zero Jacobian column).
    """
    from scipy import optimize, stats

    from rftgls_core.rft.media import custom_medium

    tests = [] if penetration is None else (
        [penetration] if isinstance(penetration, PenetrationTrace) else list(penetration))
    # F = 0.875 xi_n A depth is linear in A * depth: samples of all tests side by side, with
    # the test each sample belongs to.
    pen_x = (np.concatenate([t.depth_m * t.plate_area_m2 for t in tests]) if tests
             else np.zeros(0))
    pen_f = np.concatenate([t.force_N for t in tests]) if tests else np.zeros(0)
    n_pen = len(pen_x)
    if len(pulls) + n_pen < 3:
        raise ValueError('need at least 3 observations for 2 parameters and an error estimate')
    if not (MU_BOUNDS[0] <= x0[1] <= MU_BOUNDS[1]):
        raise ValueError(f'mu_surf start {x0[1]} outside {MU_BOUNDS}')
    # Cluster label of every residual: pull tests first (one each), then penetration tests.
    groups = np.concatenate([np.arange(len(pulls)),
                             np.concatenate([np.full(len(t.depth_m), len(pulls) + i)
                                             for i, t in enumerate(tests)])
                             if tests else np.zeros(0, dtype=int)]).astype(int)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(unit='eval', desc='calibrate', file=sys.stderr)

    def pull_forces(xi: float, mu: float) -> np.ndarray:
        med = custom_medium(xi_n=xi, mu_surf=mu)
        predictors: dict[str, Predictor] = {}
        out = np.empty(len(pulls))
        for i, ob in enumerate(pulls):
            if ob.robot not in predictors:
                predictors[ob.robot] = make_predictor(method, ob.robot, med, anchor=anchor)
            r = predictors[ob.robot].predict(ob.state, ob.phi, ob.pull)
            # No balance at this medium: the anchor holds nothing; the residual says so
            # (a NaN would stop the solver).
            out[i] = r.capacity_N if r.status.has_value and r.capacity_N is not None else 0.0
        if bar is not None:
            bar.update(1)
        return out

    meas = np.array([ob.breakaway_N for ob in pulls])
    mu_fixed = float(x0[1])

    def unpack(u: np.ndarray, fit_mu: bool) -> tuple[float, float]:
        return float(u[0]) * XI_SCALE, (math.exp(float(u[1])) if fit_mu else mu_fixed)

    def residuals(u: np.ndarray, fit_mu: bool) -> np.ndarray:
        xi, mu = unpack(u, fit_mu)
        r = [(pull_forces(xi, mu) - meas) / sigma_pull_N] if pulls else []
        if n_pen:
            r.append((PLATE_FACTOR * xi * pen_x - pen_f) / sigma_penetration_N)
        return np.concatenate(r)

    def solve(fit_mu: bool):
        u0 = [x0[0] / XI_SCALE] + ([math.log(x0[1])] if fit_mu else [])
        lo = [0.1] + ([math.log(MU_BOUNDS[0])] if fit_mu else [])
        hi = [100.0] + ([math.log(MU_BOUNDS[1])] if fit_mu else [])
        # diff_step: relative; 1e-3 keeps the finite differences above the solver's round-off
        return optimize.least_squares(residuals, np.array(u0), args=(fit_mu,),
                                      bounds=(lo, hi), diff_step=1e-3,
                                      x_scale=np.array([1.0, 0.25][:len(u0)]), xtol=1e-10,
                                      ftol=1e-10)

    fixed: dict = {}
    if pulls:
        sol = solve(True)
        col = np.linalg.norm(sol.jac, axis=0)
        if not col[1] > IDENTIFIED_REL * col.max():
            fixed['mu_surf'] = (f'not identified: the pull-test capacities do not change with '
                                f'it; fixed at {mu_fixed:g}')
            sol = solve(False)
    else:
        fixed['mu_surf'] = (f'not identified: no pull test (plate penetration does not depend '
                            f'on friction); fixed at {mu_fixed:g}')
        sol = solve(False)
    if bar is not None:
        bar.close()
    fit_mu = 'mu_surf' not in fixed
    J, res = sol.jac, sol.fun
    k = J.shape[1]
    n_tests = len(np.unique(groups))
    dof_res = len(res) - k
    s2 = float(res @ res) / dof_res if dof_res > 0 else 1.0
    cov_res = s2 * np.linalg.pinv(J.T @ J)
    sd_res = np.sqrt(np.maximum(np.diag(cov_res), 0.0))
    if n_tests > k:
        # Per parameter the wider of the two: cluster-robust over tests (the scatter between
        # them), and the pooled residual scatter, because with few tests one test that
        # carries a parameter alone (a single penetration test next to pull tests) has a
        # score of ~0 at the optimum and would make the cluster-robust variance vanish.
        sd_cr = np.sqrt(np.maximum(np.diag(_cluster_covariance(J, res, groups)), 0.0))
        sd_u = np.maximum(sd_cr, sd_res)
        basis = {n: ('between_tests' if c >= r_ else 'within_test')
                 for n, c, r_ in zip(PARAMS, sd_cr, sd_res)}
        dof = n_tests - k
    else:
        sd_u = sd_res
        basis = {n: 'within_test' for n in PARAMS[:k]}
        dof = max(dof_res, 1)
    # The residual correlation, scaled to the chosen standard deviations.
    corr = cov_res / np.outer(np.where(sd_res > 0, sd_res, 1.0), np.where(sd_res > 0, sd_res,
                                                                          1.0))
    cov_u = corr * np.outer(sd_u, sd_u)
    xi, mu = unpack(sol.x, fit_mu)
    t = float(stats.t.ppf(0.975, dof))
    # Covariance in SI by the delta method: d xi / d u0 = XI_SCALE, d mu / d log mu = mu.
    D = np.diag([XI_SCALE] + ([mu] if fit_mu else []))
    cov_k = D @ cov_u @ D
    cov = np.zeros((2, 2))
    cov[:k, :k] = cov_k
    ci95: dict = {'xi_n': (xi - t * sd_u[0] * XI_SCALE, xi + t * sd_u[0] * XI_SCALE),
                  'mu_surf': None}
    if fit_mu:   # symmetric in log mu: the interval stays positive
        ci95['mu_surf'] = (mu * math.exp(-t * sd_u[1]), mu * math.exp(t * sd_u[1]))
    ci95 = {n: (None if v is None else (float(v[0]), float(v[1]))) for n, v in ci95.items()}
    rms = {}
    pred_pull = meas + res[:len(pulls)] * sigma_pull_N
    if pulls:
        rms['pull_N'] = float(np.sqrt(np.mean((res[:len(pulls)] * sigma_pull_N) ** 2)))
    if n_pen:
        res_pen = res[len(pulls):] * sigma_penetration_N
        rms['penetration_N'] = float(np.sqrt(np.mean(res_pen ** 2)))
    scatter = {}
    if len(tests) >= 2:
        per_test = [float(np.sum(tt.depth_m * tt.plate_area_m2 * tt.force_N)
                          / (PLATE_FACTOR * np.sum((tt.depth_m * tt.plate_area_m2) ** 2)))
                    for tt in tests]
        scatter = {'xi_n_per_test': per_test,
                   'xi_n_rel_sd': float(np.std(per_test, ddof=1) / np.mean(per_test))}
    return Calibration(xi_n=float(xi), mu_surf=float(mu), cov=cov, ci95=ci95, dof=int(dof),
                       residual_rms=rms, n_pull=len(pulls), n_penetration=n_pen,
                       method=method, n_penetration_tests=len(tests), fixed=fixed,
                       interval_basis=basis, n_tests=n_tests, test_scatter=scatter,
                       penetration_tests=[(tt.test_id, tt.depth_m * tt.plate_area_m2,
                                           tt.force_N) for tt in tests],
                       pull_fit=[(ob.test_id, float(m_), float(p_))
                                 for ob, m_, p_ in zip(pulls, meas, pred_pull)])


def plot_fit(cal: Calibration, path: str | Path) -> None:
    """Fit and residual plot of one calibration (PNG): penetration force against A * depth
    per test with the fitted line, pull-test breakaway measured against predicted, and the
    residuals of both."""
    plt = pyplot()
    cols = int(bool(cal.penetration_tests)) + int(bool(cal.pull_fit))
    fig, axes = plt.subplots(2, cols, figsize=(5.5 * cols, 7), squeeze=False)
    c = 0
    if cal.penetration_tests:
        top, bot = axes[0, c], axes[1, c]
        xmax = max(float(np.max(x)) for _, x, _ in cal.penetration_tests)
        for tid, x, f in cal.penetration_tests:
            top.plot(x * 1e6, f, '.', ms=3, label=str(tid))
            bot.plot(x * 1e6, f - PLATE_FACTOR * cal.xi_n * x, '.', ms=3)
        xs = np.linspace(0.0, xmax, 2)
        top.plot(xs * 1e6, PLATE_FACTOR * cal.xi_n * xs, 'k-', lw=1.5,
                 label=f'fit xi_n = {cal.xi_n:.4g} N/m^3')
        top.set(xlabel='plate area x depth [cm^3]', ylabel='force [N]',
                title=f'plate penetration ({cal.n_penetration_tests} tests)')
        top.legend(fontsize=7, ncol=2)
        bot.axhline(0.0, color='k', lw=0.8)
        bot.set(xlabel='plate area x depth [cm^3]', ylabel='residual [N]')
        c += 1
    if cal.pull_fit:
        top, bot = axes[0, c], axes[1, c]
        meas = np.array([m for _, m, _ in cal.pull_fit])
        pred = np.array([p for _, _, p in cal.pull_fit])
        top.plot(pred, meas, 'o')
        lim = [0.0, 1.05 * float(max(meas.max(), pred.max()))]
        top.plot(lim, lim, 'k-', lw=0.8)
        top.set(xlabel='predicted breakaway [N]', ylabel='measured breakaway [N]',
                title=f'pull tests ({cal.n_pull}), {cal.method}')
        bot.bar(range(len(meas)), meas - pred)
        bot.set_xticks(range(len(meas)), [t for t, _, _ in cal.pull_fit], rotation=60,
                       fontsize=6)
        bot.axhline(0.0, color='k', lw=0.8)
        bot.set(ylabel='measured - predicted [N]')
    mu_txt = ('mu_surf fixed (not identified)' if cal.ci95['mu_surf'] is None
              else f'mu_surf {cal.mu_surf:.3f}')
    fig.suptitle(f'calibration: xi_n {cal.xi_n:.4g} N/m^3, {mu_txt}\n95 % interval of xi_n '
                 f'{cal.ci95["xi_n"][0]:.4g} .. {cal.ci95["xi_n"][1]:.4g} '
                 f'({cal.interval_basis.get("xi_n", "")})', fontsize=9)
    save(fig, path)     # layout, atomic write (a planted link replaced), free


def plot_path(out: str | Path) -> Path:
    """The fit plot written next to a calibration output: medium.json -> medium_fit.png."""
    p = Path(out)
    return p.with_name(p.stem + '_fit.png')


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
