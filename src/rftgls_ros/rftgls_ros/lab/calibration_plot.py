"""The fit/residual plot of a calibration: penetration and pull-test fits and their residuals."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rftgls_core.charts.figure_io import pyplot, save

from .calibration import PLATE_FACTOR, Calibration


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
