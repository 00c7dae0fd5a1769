"""The paper's Figs. 4-6 for one pose: wrench cloud, limit surface, limit curve at My = 0, load
ray, capacity point and slip twist. Axes in N and N m (external-load space about p)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..predictor.live import RobotPredictor
from ..types import AnchorState, Pull, pull_direction
from .figure_io import pyplot, save


def limit_curve(predictor: RobotPredictor, state: AnchorState, pull: Pull | str, n: int = 181):
    """Capacity over all tether angles: the GLS cut by the plane My = 0 (the paper's F)."""
    phis = np.linspace(-math.pi, math.pi, n)
    results = predictor.predict_many(state, phis, pull)
    caps = np.array([np.nan if r.capacity_N is None else r.capacity_N for r in results])
    dirs = np.array([pull_direction(p)[:2] for p in phis])
    return phis, caps, dirs * caps[:, None]


def plot_limit_surface(predictor: RobotPredictor, state: AnchorState, pull: Pull | str, phi: float,
                       out: str | Path, title: str = '') -> dict:
    """Write a two-panel PNG; returns the capacity result at phi for captions and logs."""
    plt = pyplot()

    surface, failure = predictor.fit(state, pull)
    result = surface.capacity(phi) if surface is not None else failure
    assert result is not None  # fit() returns a surface or a failure result
    fig = plt.figure(figsize=(13, 6))
    ax3 = fig.add_subplot(1, 2, 1, projection='3d')
    ax2 = fig.add_subplot(1, 2, 2)
    cloud = getattr(surface, 'wrenches_scaled', None)   # twist-mesh keeps its wrench cloud
    if cloud is not None:
        w = predictor.scaling.wrench_from_scaled(cloud)
        ax3.scatter(w[:, 0], w[:, 1], w[:, 2], s=2, c='0.4', alpha=0.35, label='RFT wrench cloud')
        faces = getattr(getattr(surface, 'sphere', None), 'faces', None)
        if faces is not None:
            ax3.plot_trisurf(w[:, 0], w[:, 1], w[:, 2], triangles=faces, color='tab:blue',
                             alpha=0.12, linewidth=0)
    _, _, curve = limit_curve(predictor, state, pull)
    ax3.plot(curve[:, 0], curve[:, 1], 0 * curve[:, 0], color='tab:orange', lw=2,
             label='limit curve (My = 0)')
    ax2.plot(curve[:, 0], curve[:, 1], color='tab:orange', lw=2, label='limit curve (My = 0)')
    d = np.array(pull_direction(phi))
    cap = result.capacity_N
    reach = cap if cap is not None else np.nanmax(np.linalg.norm(curve, axis=1), initial=1.0)
    ray = np.outer([0, 1.3 * reach], d)
    for ax in (ax2,):
        ax.plot(ray[:, 0], ray[:, 1], 'k--', lw=1,
                label=f'load ray phi = {math.degrees(phi):.0f} deg')
        ax.plot(0, 0, 'k+', ms=10)
    ax3.plot(ray[:, 0], ray[:, 1], ray[:, 2], 'k--', lw=1)
    if cap is not None:
        point = cap * d
        ax2.plot(point[0], point[1], 'o', color='tab:red', label=f'capacity {cap:.2f} N')
        ax3.scatter([point[0]], [point[1]], [0], color='tab:red', s=40)
        t = np.asarray(result.slip_twist_scaled)
        scale = 0.25 * reach
        ax2.annotate('', xy=(point[0] + scale * t[0], point[1] + scale * t[1]), xytext=point[:2],
                     arrowprops=dict(arrowstyle='->', color='tab:green', lw=2))
        ax2.plot([], [], color='tab:green', label='slip twist (vx, vz), scaled metric')
    ax3.set_xlabel('Fx [N]')
    ax3.set_ylabel('Fz [N]')
    ax3.set_zlabel('My [N m]')
    ax3.set_title('granular limit surface (external load about p)')
    ax2.set_xlabel('Fx [N]')
    ax2.set_ylabel('Fz [N]')
    ax2.axhline(0, color='0.8', lw=0.5)
    ax2.axvline(0, color='0.8', lw=0.5)
    ax2.set_aspect('equal', adjustable='datalim')
    ax2.legend(loc='best', fontsize=8)
    status = result.status.value + (f' ({result.reason})' if result.reason else '')
    ax2.set_title(f'limit curve and load capacity: {status}')
    deg = [math.degrees(a) for a in state.as_tuple()[1:]]
    robot, medium = predictor.robot.name, predictor.medium.name
    fig.suptitle(title or (f'{robot}, {medium}, {Pull(pull).value} pull, '
                           f'h = {1e3 * state.h:.0f} mm, thetaB = {deg[0]:.1f}, '
                           f'thetaL1 = {deg[1]:.0f}, thetaL2 = {deg[2]:.0f} deg, '
                           f'method {predictor.method}'))
    save(fig, out)
    return {'capacity_N': cap, 'status': result.status.value, 'reason': result.reason}
