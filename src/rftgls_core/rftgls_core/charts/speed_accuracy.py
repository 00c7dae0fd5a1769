"""The speed/accuracy chart: time per query against error, one point per configuration."""
from __future__ import annotations

import math
from pathlib import Path

from ..accuracy import Summary, pareto_front
from .figure_io import pyplot, save

COLORS = {'twist-mesh': 'tab:blue', 'direct': 'tab:green', 'alpha': 'tab:purple',
          'ellipsoid': 'tab:orange', 'map': 'tab:red'}


def plot_speed_accuracy(summaries: list[Summary], out: str | Path, title: str = '') -> None:
    plt = pyplot()

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    panels = (('cap_err_pct_p95', 'capacity error, 95th percentile [%]'),
              ('twist_err_deg_p95', 'slip-twist error, 95th percentile [deg, scaled metric]'))
    for ax, (key, label) in zip(axes, panels):
        pts = [(s.time_ms_median, getattr(s, key)) for s in summaries]
        ok = [i for i, p in enumerate(pts) if math.isfinite(p[1])]
        floor = 1e-4
        for i in ok:
            s = summaries[i]
            y = max(pts[i][1], floor)
            ax.scatter(pts[i][0], y, color=COLORS.get(s.method, 'k'), s=36, zorder=3)
            name, _, res = s.config.partition(' N=')
            ax.annotate(f'{name}\nN={res}', (pts[i][0], y), fontsize=6, xytext=(3, 3),
                        textcoords='offset points')
        front = [ok[j] for j in pareto_front([pts[i] for i in ok])]
        fx = [pts[i][0] for i in front]
        fy = [max(pts[i][1], floor) for i in front]
        ax.step(fx, fy, where='post', color='k', lw=1, ls='--', label='Pareto front')
        ax.set_xscale('log')
        ax.set_yscale('log')
        ax.set_xlabel('time per query from scratch [ms] (pose + RFT + fit + query)')
        ax.set_ylabel(label)
        ax.grid(True, which='both', alpha=0.3)
        for m, c in COLORS.items():
            if any(s.method == m for s in summaries):
                ax.scatter([], [], color=c, label=m)
        ax.legend(fontsize=8)
    fig.suptitle(title or 'speed against accuracy (reference: direct on the finest leg mesh)')
    save(fig, out)
