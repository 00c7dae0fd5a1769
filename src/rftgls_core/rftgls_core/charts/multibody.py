"""A simulated gait at a glance: body, legs and sand at a few instants, and the servo torques."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..multibody.results import SimResult
from ..multibody.robot import BasePose, Multibody
from .figure_io import save


def _outline(mesh, rot: np.ndarray, org: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and z (mm) of a mesh's vertices (a side view's point cloud)."""
    v = mesh.vertices @ rot.T + org
    return v[:, 0] * 1e3, v[:, 2] * 1e3


def plot_run(robot: Multibody, res: SimResult, path: str | Path, title: str = '',
             instants: int = 5) -> Path:
    """Side views of the robot at `instants` times (sand surface at z = 0) above the servo
    torques and the height of p against time; PNG at path."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    samples = res.samples
    fig = plt.figure(figsize=(11, 7.5))
    gs = fig.add_gridspec(2, instants, height_ratios=[1.0, 1.0])
    picks: list[int] = (np.linspace(0, len(samples) - 1, instants).round().astype(int).tolist()
                        if samples else [])
    colours = plt.get_cmap('tab10')
    for col, k in enumerate(picks):
        ax = fig.add_subplot(gs[0, col])
        s = samples[k]
        pose = BasePose(s.x, s.z, s.theta_b)
        rot, org = pose.rotation, pose.origin
        ax.axhspan(-80, 0, color='#e8d8a8', zorder=0)
        ax.axhline(0.0, color='#a08040', lw=1)
        if robot.base_mesh is not None:
            x, z = _outline(robot.base_mesh, rot, org)
            ax.scatter(x, z, s=1, color='0.3')
        for i, leg in enumerate(robot.legs):
            if leg.mesh is None:
                continue
            lr = rot @ leg.rotation(float(s.q[i]))
            x, z = _outline(leg.mesh, lr, org + rot @ leg.hip)
            ax.scatter(x, z, s=1, color=colours(i % 10))
        p = org + rot @ robot.tether
        ax.plot(p[0] * 1e3, p[2] * 1e3, 'k^', ms=5)
        ax.set_aspect('equal')
        ax.set_xlim(p[0] * 1e3 - 80, p[0] * 1e3 + 230)
        ax.set_ylim(-80, 200)
        ax.set_title(f't = {s.t:.2f} s\n{s.phase}', fontsize=8)
        ax.tick_params(labelsize=7)
        if col == 0:
            ax.set_ylabel('z, mm')
        ax.set_xlabel('x, mm', fontsize=8)
    t = np.array([s.t for s in samples])
    ax = fig.add_subplot(gs[1, :instants - 1])
    tau = np.array([s.torques for s in samples]) if samples else np.zeros((0, len(robot.legs)))
    for i, leg in enumerate(robot.legs):
        ax.plot(t, tau[:, i], color=colours(i % 10), lw=1, label=leg.name)
        st = np.array([s.stalled[i] for s in samples], dtype=bool)
        if st.any():
            ax.plot(t[st], tau[st, i], 'x', color=colours(i % 10), ms=3)
    ax.axhline(0.0, color='0.6', lw=0.5)
    ax.set_xlabel('t, s')
    ax.set_ylabel('servo torque, N m (x: stalled)')
    ax.legend(fontsize=7, ncol=2)
    ax2 = fig.add_subplot(gs[1, instants - 1])
    ax2.plot(t, [s.pz * 1e3 for s in samples], 'k-', lw=1, label='h (p), mm')
    ax2.plot(t, [math.degrees(s.theta_b) for s in samples], 'r-', lw=1, label='theta_b, deg')
    ax2.set_xlabel('t, s')
    ax2.legend(fontsize=7)
    fig.suptitle(f'{title}  [{res.status.value}{": " + res.reason if not res.ok else ""}]',
                 fontsize=10)
    path = Path(path)
    save(fig, path, dpi=110)    # atomic, through safe_write; closes the figure
    return path
