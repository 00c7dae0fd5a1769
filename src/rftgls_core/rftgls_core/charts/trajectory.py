"""Force and trajectory traces of slipping anchors (the paper's Fig. 8 layout)."""
from __future__ import annotations

import math
from pathlib import Path

from .figure_io import pyplot, save


def plot_trajectories(runs: dict, out: str | Path, title: str = '', measured: dict | None = None
                      ) -> None:
    """runs: label -> Trajectory. Rows: pull force, z of p, thetaB; all against x of p (mm)."""
    plt = pyplot()

    fig, axes = plt.subplots(3, 1, figsize=(6, 8), sharex=True)
    for label, traj in runs.items():
        a = traj.as_array()
        if len(a) == 0:
            continue
        x = -1e3 * a[:, 1]  # pulled toward -x: plot the pull-out distance as positive
        axes[0].plot(x, a[:, 4], label=label)
        axes[1].plot(x, 1e3 * a[:, 2], label=label)
        axes[2].plot(x, [math.degrees(v) for v in a[:, 3]], label=label)
        axes[1].plot(x[-1:], 1e3 * a[-1:, 2], 'kx')
    for label, m in (measured or {}).items():
        axes[0].plot(m['x_mm'], m['force_N'], 'k-', lw=1.5, label=label)
        axes[1].plot(m['x_mm'], m['z_mm'], 'k-', lw=1.5)
        axes[2].plot(m['x_mm'], m['theta_b_deg'], 'k-', lw=1.5)
    axes[0].set_ylabel('pull force [N]')
    axes[1].set_ylabel('z of p [mm]')
    axes[2].set_ylabel('thetaB [deg]')
    axes[2].set_xlabel('pull-out displacement of p, -x [mm]')
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    save(fig, out)
