"""Capacity of a posed anchor (a rigid body or a robot) against the tether's yaw and its angle.

Left: capacity against yaw at a fixed tether angle phi (a yawed pull is a load out of the
sagittal plane: the 6D path answers it). Right: capacity against phi at a fixed yaw, drawn in
the pull plane as the limit curve (the limit surface cut by the plane of the tether, with no
moment about the tether point). Each point says which path answered (sagittal or 6D).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..posed import PosedAnchor, PosedAnchorSolver
from .figure_io import pyplot, save


def capacity_sweep(solver: PosedAnchorSolver, posed: PosedAnchor, phis, yaws) -> dict:
    """Capacities (N, NaN without a value), statuses and spaces for every (phi, yaw) pair of
    the two 1D sweeps (rad)."""
    out: dict = {'phi_rad': [], 'yaw_rad': [], 'capacity_N': [], 'status': [], 'space': []}
    for phi, yaw in zip(phis, yaws):
        r = solver.solve(posed, float(phi), float(yaw))
        out['phi_rad'].append(float(phi))
        out['yaw_rad'].append(float(yaw))
        out['capacity_N'].append(r.capacity_N)
        out['status'].append(r.status.value)
        out['space'].append(r.space)
    return out


def plot_posed_capacity(solver: PosedAnchorSolver, posed: PosedAnchor, phi: float, yaw: float,
                        out: str | Path, n_yaw: int = 19, n_phi: int = 37,
                        title: str = '') -> dict:
    """Write the two-panel PNG; returns both sweeps (for JSON next to it)."""
    plt = pyplot()
    yaws = np.linspace(-math.pi / 2, math.pi / 2, n_yaw)
    by_yaw = capacity_sweep(solver, posed, np.full(n_yaw, phi), yaws)
    phis = np.linspace(-math.pi / 2, math.pi / 2, n_phi)
    by_phi = capacity_sweep(solver, posed, phis, np.full(n_phi, yaw))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    cap = np.array([np.nan if c is None else c for c in by_yaw['capacity_N']])
    space = np.array(by_yaw['space'])
    deg = np.degrees(yaws)
    ax1.plot(deg, cap, '-', color='0.6')
    for name, marker in (('sagittal', 'o'), ('6d', 's')):
        m = space == name
        ax1.plot(deg[m], cap[m], marker, ls='', label=f'{name} path')
    ax1.set_xlabel('tether yaw [deg]')
    ax1.set_ylabel('load capacity [N]')
    ax1.set_title(f'capacity against yaw, phi = {math.degrees(phi):.0f} deg')
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    cp = np.array([np.nan if c is None else c for c in by_phi['capacity_N']])
    # In the pull plane: horizontal component along the horizontal pull, vertical up.
    ax2.plot(-cp * np.cos(phis), cp * np.sin(phis), 'o-', color='tab:orange',
             label='capacity along the tether')
    ax2.plot(0, 0, 'k+', ms=10)
    ax2.set_xlabel('horizontal pull component, away from the body [N] (negative)')
    ax2.set_ylabel('vertical pull component [N]')
    ax2.set_title(f'limit curve in the pull plane, yaw = {math.degrees(yaw):.0f} deg')
    ax2.set_aspect('equal', adjustable='datalim')
    ax2.grid(alpha=0.3)
    ax2.legend(fontsize=8)
    fig.suptitle(title or f'{posed.name}: {solver.medium.name}')
    save(fig, out)
    return {'by_yaw': by_yaw, 'by_phi': by_phi}
