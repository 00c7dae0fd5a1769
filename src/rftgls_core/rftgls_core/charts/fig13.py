"""The paper's Fig. 13 from our model: an ellipsoid anchor pulled out at constant tether angles.

The paper (sec. VII-B) buries a 3D-printed ellipsoid at 7 cm depth with a 30 deg body angle,
pulls it out with a robot arm at a constant tension angle phi, and compares predicted and
tracked trajectories (panels b, c: the tether point's path, the anchor's orientation) and load
capacities (panel d). It gives neither the ellipsoid's size nor the medium's parameters, so
these are assumptions (also written into the JSON):

- semi-axes 30 x 20 x 12.5 mm (a 60 x 40 x 25 mm body: printable on any desktop printer,
  a few times the 0.8 mm beads), long axis in the pull plane;
- mass 40 g (solid PLA, 1.24 g/cm^3, of that volume), centre of mass at its centroid;
- the tether at the end of the long axis, on the surface of the body;
- "7 cm depth": the centre of the ellipsoid 70 mm below the free surface; "30 deg body angle":
  the long axis 30 deg below the horizontal from the tether end (the far end deeper, the nose
  toward the pull);
- medium: the paper's 0.8 mm glass beads (preset `glass_beads`), Agarwal 3D-RFT.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..body import RigidBody
from ..geometry.shapes import ellipsoid
from ..posed import PosedAnchorSolver
from ..rft.media import get_medium
from ..sim.body_pull import BodyAnchor, BodyPredictor
from ..sim.trajectory import simulate_pull
from ..types import AnchorState, Pull
from .figure_io import pyplot, save

SEMI_AXES_M = (0.030, 0.020, 0.0125)
MASS_KG = 0.040
CENTRE_DEPTH_M = 0.070
BODY_ANGLE_DEG = 30.0
MEDIUM = 'glass_beads'
TRAJECTORY_PHIS_DEG = (30.0, 60.0, 90.0)
CAPACITY_PHIS_DEG = tuple(float(p) for p in range(0, 91, 10))


def ellipsoid_anchor(subdivisions: int = 3) -> BodyAnchor:
    """The assumed Fig. 13 ellipsoid, its mesh frame B with the tether point at the origin
    and the body along +x_B."""
    a, b, c = SEMI_AXES_M
    mesh = ellipsoid(a, b, c, subdivisions).transformed(np.eye(3), np.array([a, 0.0, 0.0]))
    return BodyAnchor(RigidBody('fig13 ellipsoid', mesh, MASS_KG))


def initial_state() -> AnchorState:
    """Tether point height and body angle of the buried ellipsoid (far end deeper)."""
    beta = math.radians(BODY_ANGLE_DEG)
    h = -CENTRE_DEPTH_M + SEMI_AXES_M[0] * math.sin(beta)
    return AnchorState(h, -beta, 0.0, 0.0)


def fig13_data(method: str = 'twist-mesh', step: float = 0.002, max_travel: float = 0.12,
               progress=None) -> tuple[dict, dict]:
    """(numbers for the JSON, trajectories by tether angle) of the figure."""
    anchor = ellipsoid_anchor()
    solver = PosedAnchorSolver(get_medium(MEDIUM), method=method)
    predictor = BodyPredictor(anchor, solver)
    state0 = initial_state()
    caps = {}
    for phi in CAPACITY_PHIS_DEG:
        r = predictor.predict(state0, math.radians(phi))
        caps[phi] = {'capacity_N': r.capacity_N, 'status': r.status.value, 'reason': r.reason,
                     'flags': list(r.flags)}
    trajs = {}
    for phi in TRAJECTORY_PHIS_DEG:
        trajs[phi] = simulate_pull(predictor, state0, math.radians(phi), Pull.BACKWARD,
                                   lambda st: -st.h, step=step, max_travel=max_travel,
                                   progress=progress)
    data = {
        'assumptions': {'semi_axes_m': list(SEMI_AXES_M), 'mass_kg': MASS_KG,
                        'centre_depth_m': CENTRE_DEPTH_M, 'body_angle_deg': BODY_ANGLE_DEG,
                        'tether': 'end of the long axis', 'medium': MEDIUM, 'rft_model':
                        'agarwal', 'method': method, 'step_m': step,
                        'stop': 'tether point reaches the free surface, no balance, or '
                                f'{max_travel * 1e3:.0f} mm of travel'},
        'initial_state': {'h_m': state0.h, 'theta_b_deg': math.degrees(state0.theta_b)},
        'capacity_by_phi_deg': {str(k): v for k, v in caps.items()},
        'trajectories': {str(phi): {'x_m': t.as_array()[:, 1].tolist(),
                                    'z_m': t.as_array()[:, 2].tolist(),
                                    'theta_b_deg': np.degrees(t.as_array()[:, 3]).tolist(),
                                    'force_N': [None if math.isnan(f) else f
                                                for f in t.as_array()[:, 4]],
                                    'stop_reason': t.stop_reason.replace(
                                        'body plate', 'tether point')}
                         for phi, t in trajs.items()},
    }
    return data, trajs


def plot_fig13(data: dict, trajs: dict, out: str | Path) -> None:
    """Panels like the paper's (b)-(d): path of the tether point, anchor angle, capacity."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    for phi, t in trajs.items():
        a = t.as_array()
        if len(a) == 0:
            continue
        lab = f'phi = {phi:.0f} deg'
        axes[0].plot(-1e3 * a[:, 1], 1e3 * a[:, 2], '-', label=lab)
        axes[1].plot(1e3 * a[:, 2], -np.degrees(a[:, 3]), '-', label=lab)
    axes[0].axhline(0.0, color='0.5', lw=1)
    axes[0].set_xlabel('tether point, horizontal displacement toward the pull [mm]')
    axes[0].set_ylabel('tether point height z [mm]')
    axes[0].set_title('(b) path of the tether point')
    axes[0].set_aspect('equal', adjustable='datalim')
    axes[1].set_xlabel('tether point height z [mm] (pulled out: left to right)')
    axes[1].set_ylabel('body angle, far end below the tether end [deg]')
    axes[1].set_title('(c) orientation of the anchor')
    caps = data['capacity_by_phi_deg']
    phis = [float(k) for k in caps]
    vals = [np.nan if v['capacity_N'] is None else v['capacity_N'] for v in caps.values()]
    axes[2].plot(phis, vals, 'o-', color='tab:red')
    axes[2].set_xlabel('tether angle phi [deg]')
    axes[2].set_ylabel('load capacity at the initial pose [N]')
    axes[2].set_title('(d) load capacity')
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    a_ = data['assumptions']
    fig.suptitle(f'Fig. 13 from our model: ellipsoid {2e3 * a_["semi_axes_m"][0]:.0f} x '
                 f'{2e3 * a_["semi_axes_m"][1]:.0f} x {2e3 * a_["semi_axes_m"][2]:.0f} mm, '
                 f'{a_["mass_kg"] * 1e3:.0f} g, centre {a_["centre_depth_m"] * 1e3:.0f} mm deep, '
                 f'{a_["body_angle_deg"]:.0f} deg, {a_["medium"]} (assumed)')
    save(fig, out)
