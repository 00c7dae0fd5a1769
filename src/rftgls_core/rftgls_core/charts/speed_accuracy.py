"""The speed/accuracy/coverage chart: one row of numbers per configuration, three panels.

Left and middle: time per query against the capacity and slip-twist errors (95th percentile,
where both the configuration and the reference carry a value), with the Pareto front. Right:
coverage, the share of every query each configuration answers, split by outcome (ok, each
status:reason), with the queries the reference itself does not answer counted, not dropped.
Points carry a number instead of a text label (labels overlap); the key is the coverage
panel's y axis.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..accuracy import Summary, pareto_front
from .figure_io import pyplot, save

COLORS = {'twist-mesh': 'tab:blue', 'direct': 'tab:green', 'alpha': 'tab:purple',
          'ellipsoid': 'tab:orange', 'map': 'tab:red', 'brute-force': 'tab:gray'}
OUTCOME_COLORS = {'ok': '#4caf50', 'unsupported': '#9e9e9e', 'degenerate': '#e53935',
                  'invalid_input': '#8e24aa', 'out_of_range': '#fb8c00', 'stale': '#3949ab'}


def _outcome_colour(key: str, k: int, plt) -> str:
    status = key.partition(':')[0]
    if status in OUTCOME_COLORS and ':' not in key:
        return OUTCOME_COLORS[status]
    return plt.get_cmap('tab20')(k % 20)


def plot_speed_accuracy(summaries: list[Summary], out: str | Path, title: str = '') -> None:
    plt = pyplot()
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    fig, axes = plt.subplots(1, 3, figsize=(19, 7), gridspec_kw={'width_ratios': [1, 1, 1.1]})
    panels = (('cap_err_pct_p95', 'capacity error, 95th percentile [%]'),
              ('twist_err_deg_p95', 'slip-twist error, 95th percentile [deg, scaled metric]'))
    floor = 1e-4
    for ax, (key, label) in zip(axes[:2], panels):
        pts = [(s.time_ms_median, getattr(s, key)) for s in summaries]
        ok = [i for i, p in enumerate(pts) if math.isfinite(p[1])]
        for i in ok:
            s = summaries[i]
            y = max(pts[i][1], floor)
            ax.scatter(pts[i][0], y, color=COLORS.get(s.method, 'k'), s=90, zorder=3,
                       edgecolor='white', linewidth=0.5)
            ax.text(pts[i][0], y, str(i + 1), fontsize=6.5, ha='center', va='center',
                    color='white', zorder=4, fontweight='bold')
        front = [ok[j] for j in pareto_front([pts[i] for i in ok])]
        ax.step([pts[i][0] for i in front], [max(pts[i][1], floor) for i in front],
                where='post', color='k', lw=1, ls='--', label='Pareto front')
        ax.set_xscale('log')
        ax.set_yscale('log')
        # Minor tick labels of a short log range overlap: keep the major ones only.
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.xaxis.set_major_formatter(FormatStrFormatter('%g'))
        ax.set_xlabel('time per query from scratch [ms] (pose + RFT + fit + query)')
        ax.set_ylabel(label)
        ax.grid(True, which='both', alpha=0.3)
        for m, c in COLORS.items():
            if any(s.method == m for s in summaries):
                ax.scatter([], [], color=c, label=m)
        ax.legend(fontsize=8, loc='lower left')

    ax = axes[2]
    keys = sorted({k for s in summaries for k in s.outcomes}, key=lambda k: (k != 'ok', k))
    names = [f'{i + 1}. {s.config}' for i, s in enumerate(summaries)]
    left = [0.0] * len(summaries)
    for k, key in enumerate(keys):
        share = [100.0 * s.outcomes.get(key, 0) / max(s.queries, 1) for s in summaries]
        ax.barh(names, share, left=left, color=_outcome_colour(key, k, plt), label=key,
                edgecolor='white', linewidth=0.3)
        left = [a + b for a, b in zip(left, share)]
    for i, s in enumerate(summaries):
        ax.text(101, i, f'{s.answered_where_ref_pct:.0f}%', va='center', fontsize=7)
    ax.set_xlim(0, 112)
    ax.invert_yaxis()
    ax.tick_params(axis='y', labelsize=7)
    ax.set_xlabel('share of all queries by outcome [%]\n(right of the bars: share answered '
                  'where the reference answers)')
    ax.legend(fontsize=7, loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=3)
    ax.set_title('coverage', fontsize=10)
    fig.suptitle(title or 'speed, accuracy and coverage (reference: direct on the finest leg '
                          'mesh; numbers index the coverage rows)')
    fig.tight_layout()
    save(fig, out)
