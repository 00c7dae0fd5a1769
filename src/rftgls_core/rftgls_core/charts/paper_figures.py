"""The paper's views recomputed from our model: Fig. 8 (traces), Fig. 9 (maps over the leg
angles), Fig. 10 b (anchor modes against sled forces).

Peak pull force = the largest capacity along the first `travel` of the quasi-static slip (the
paper: the peak sometimes comes after the robot starts to move). Slopes over the same slip:
dz/dx = (z_end - z0) / (pull-out distance), dthetaB/|dx| in deg/mm; the pull-out distance is
positive along the pull (-x), so a point p that sinks while it is pulled out has dz/dx < 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..predictor.live import RobotPredictor
from ..sim.trajectory import Trajectory, simulate_pull
from ..types import AnchorState, Pull
from .figure_io import pyplot, save

LEG_ANGLES_DEG = (-40, -20, 0, 20, 40)


@dataclass(frozen=True)
class SlipSummary:
    peak_force_N: float        # NaN when the pose has no balance
    dz_dx: float
    dthetab_deg_per_mm: float
    stop_reason: str


def slip_summary(predictor: RobotPredictor, state: AnchorState, pull: Pull | str, phi: float = 0.0,
                 travel: float = 0.02, step: float = 0.002) -> tuple[SlipSummary, Trajectory]:
    plate = lambda st: predictor.robot.pose(st, pull).plate_min_z
    traj = simulate_pull(predictor, state, phi, pull, plate, step=step, max_travel=travel)
    a = traj.as_array()
    forces = a[:, 4]
    if len(a) < 2 or not np.any(np.isfinite(forces)):
        return SlipSummary(math.nan, math.nan, math.nan, traj.stop_reason), traj
    dx = -(a[-1, 1] - a[0, 1])
    dz = a[-1, 2] - a[0, 2]
    dtb = math.degrees(a[-1, 3] - a[0, 3])
    return SlipSummary(float(np.nanmax(forces)), dz / dx if dx > 0 else math.nan,
                       dtb / (1e3 * abs(dx)) if dx != 0 else math.nan, traj.stop_reason), traj


def leg_angle_maps(predictor: RobotPredictor, h: float = 0.02, theta_b: float = 0.0,
                   progress=None) -> dict:
    """Fig. 9 data: {pull: {'peak': (5, 5), 'dz_dx': ..., 'dtb': ...}}, rows thetaL1, cols L2."""
    out = {}
    for pull in (Pull.FORWARD, Pull.BACKWARD):
        grids = {k: np.full((5, 5), np.nan) for k in ('peak', 'dz_dx', 'dtb')}
        for i, l1 in enumerate(LEG_ANGLES_DEG):
            for j, l2 in enumerate(LEG_ANGLES_DEG):
                st = AnchorState(h, theta_b, math.radians(l1), math.radians(l2))
                s, _ = slip_summary(predictor, st, pull)
                grids['peak'][i, j] = s.peak_force_N
                grids['dz_dx'][i, j] = s.dz_dx
                grids['dtb'][i, j] = s.dthetab_deg_per_mm
                if progress:
                    progress(1)
        out[pull.value] = grids
    return out


def plot_leg_angle_maps(maps: dict, out: str | Path, title: str) -> None:
    plt = pyplot()

    rows = (('peak', 'peak pull force [N]'), ('dz_dx', 'dz/dx [-]'),
            ('dtb', 'dthetaB/|dx| [deg/mm]'))
    fig, axes = plt.subplots(3, 2, figsize=(10, 12))
    for c, pull in enumerate(('forward', 'backward')):
        for r, (key, label) in enumerate(rows):
            ax = axes[r, c]
            g = maps[pull][key]
            im = ax.imshow(g, origin='lower', cmap='viridis',
                           extent=(-50, 50, -50, 50))
            for i, l1 in enumerate(LEG_ANGLES_DEG):
                for j, l2 in enumerate(LEG_ANGLES_DEG):
                    txt = '—' if not np.isfinite(g[i, j]) else f'{g[i, j]:.2f}'
                    ax.text(l2, l1, txt, ha='center', va='center', fontsize=7, color='w')
            ax.set_xticks(LEG_ANGLES_DEG)
            ax.set_yticks(LEG_ANGLES_DEG)
            ax.set_xlabel('thetaL2 [deg]')
            ax.set_ylabel('thetaL1 [deg]')
            ax.set_title(f'{pull}: {label}')
            fig.colorbar(im, ax=ax, shrink=0.8)
    fig.suptitle(title + '\n(— : no quasi-static balance)')
    save(fig, out, dpi=100)


def plot_anchor_modes(capacities: dict, needs: dict, out: str | Path, title: str,
                      lower: dict | None = None) -> None:
    """Fig. 10 b: capacities[mode][phi_deg] (N or None) against sled forces needs[label];
    lower[mode][phi_deg]: one-sided 95 % lower bounds, drawn as error bars."""
    plt = pyplot()

    modes = list(capacities)
    phis = sorted({p for m in capacities.values() for p in m}, reverse=True)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    width = 0.8 / len(phis)
    for k, phi in enumerate(phis):
        vals = [capacities[m][phi] or 0.0 for m in modes]
        xs = np.arange(len(modes)) + (k - (len(phis) - 1) / 2) * width
        ax.bar(xs, vals, width, label=f'phi = {phi:.0f} deg')
        if lower:
            lo = [max(v - (lower[m][phi] if lower[m][phi] is not None else v), 0.0)
                  for m, v in zip(modes, vals)]
            ax.errorbar(xs, vals, yerr=[lo, [0.0] * len(lo)], fmt='none', ecolor='k',
                        capsize=4, lw=1)
    if lower:
        ax.errorbar([], [], yerr=[], fmt='none', ecolor='k', capsize=4,
                    label='95 % lower bound (medium uncertainty)')
    for (label, force), ls in zip(needs.items(), ('--', ':', '-.')):
        ax.axhline(force, color='k', ls=ls, lw=1, label=f'{label} sled: {force:.2f} N')
    ax.set_xticks(range(len(modes)))
    ax.set_xticklabels(modes)
    ax.set_ylabel('load capacity [N]')
    ax.legend(fontsize=8)
    ax.set_title(title)
    save(fig, out)
