"""Calibration uncertainty over separate tests.

Reference width, worked out here from the construction, not from the code under test: five
plate-penetration tests whose own xi_n values are xi_true (1 + 0.15 z_i), with z standardised
(mean 0, sample sd 1), scatter by exactly 15 % (1 sd) between tests. The medium's xi_n is their
mean, whose standard error is 0.15 xi_true / sqrt(5); with 5 - 1 = 4 degrees of freedom the
95 % interval is the mean +- t(0.975, 4) * 0.15 / sqrt(5) = +- 2.776 * 0.0671 = +- 18.6 % of
xi_true (the textbook one-sample t interval of the test means; the within-test noise of 0.05 N
adds about 0.01 %). Tolerance: +- 1 percentage point on the half-width.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from rftgls_ros.lab.calibrate import main
from rftgls_ros.lab.calibration import PenetrationTrace, calibrate

XI_TRUE = 4.0e5
AREA = 0.04 * 0.04
SCATTER = 0.15


def five_tests(seed: int = 3) -> list[PenetrationTrace]:
    rng = np.random.default_rng(seed)
    z = rng.normal(size=5)
    z = (z - z.mean()) / z.std(ddof=1)              # exactly mean 0, sd 1
    depth = np.linspace(0.002, 0.04, 30)
    return [PenetrationTrace(depth, 0.875 * XI_TRUE * (1 + SCATTER * zi) * AREA * depth
                             + rng.normal(0, 0.05, depth.size), AREA, f'push{i}')
            for i, zi in enumerate(z)]


def test_interval_reflects_the_scatter_between_tests():
    cal = calibrate([], five_tests())
    expected = stats.t.ppf(0.975, 4) * SCATTER / math.sqrt(5)       # 0.1862
    assert expected == pytest.approx(0.1862, abs=1e-4)
    lo, hi = cal.ci95['xi_n']
    half = 0.5 * (hi - lo) / XI_TRUE
    assert half == pytest.approx(expected, abs=0.01), (lo, hi)
    assert cal.xi_n == pytest.approx(XI_TRUE, rel=0.005)
    assert cal.interval_basis == {'xi_n': 'between_tests'} and cal.dof == 4
    assert cal.test_scatter['xi_n_rel_sd'] == pytest.approx(SCATTER, rel=0.01)
    # the pooled samples alone would claim ~ +-1 % (the complaint): far narrower
    assert half > 10 * 0.01


def test_one_test_falls_back_to_its_residuals():
    cal = calibrate([], five_tests()[:1])
    assert cal.interval_basis == {'xi_n': 'within_test'} and cal.n_tests == 1
    lo, hi = cal.ci95['xi_n']
    assert lo < cal.xi_n < hi and (hi - lo) / cal.xi_n < 0.01


def test_mu_surf_not_identified_without_pull_tests(tmp_path, capsys):
    # five tests in one file with a `test` column, through the CLI: null in ci95, a plot
    rows = ['depth_m,force_N,test']
    for t in five_tests():
        rows += [f'{float(d)!r},{float(f)!r},{t.test_id}' for d, f in zip(t.depth_m, t.force_N)]
    csv = tmp_path / 'pushes.csv'
    csv.write_text('\n'.join(rows) + '\n')
    out = tmp_path / 'medium.json'
    assert main(['--penetration', str(csv), '--plate-area', str(AREA), '--out', str(out)]) == 0
    d = json.loads(out.read_text())
    cal = d['calibration']
    assert cal['ci95']['mu_surf'] is None and cal['std']['mu_surf'] is None
    assert 'not identified' in cal['fixed']['mu_surf']
    assert d['mu_surf'] == pytest.approx(0.4)           # the start value, not a fit
    assert cal['n_penetration_tests'] == 5 and cal['n_tests'] == 5
    lo, hi = cal['ci95']['xi_n']
    assert (hi - lo) / 2 / XI_TRUE == pytest.approx(0.1862, abs=0.01)
    png = tmp_path / 'medium_fit.png'
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 10_000
    assert 'not identified' in capsys.readouterr().out
