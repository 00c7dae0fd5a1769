"""Fitting the medium's two Agarwal parameters (xi_n, mu_surf) to pull tests and plate penetration.

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
The command line (lab/calibrate.py) writes a fit/residual plot next to its output
(lab/calibration_plot.py: medium.json -> medium_fit.png).
"""
from __future__ import annotations

import csv
import io
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rftgls_conventions.safe_read import read_text
from rftgls_core.predictor import Predictor
from rftgls_core.rft.media import Medium
from rftgls_core.types import AnchorState

from .bag_layout import PullTest
from .evaluate import running_median
from .predict import (
    LabAnchor,
    initial_pose,
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


