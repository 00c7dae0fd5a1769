"""Gaits a robot cannot run, refused before a run starts (GaitError, one line).

- a joint outside its range: a leg whose joint has limits (robot.Leg.limits: URDF revolute
  joints narrower than a full turn) may not be sent outside them at any instant of the gait;
- a leg through the body: no leg point may enter the base's mesh at any instant, except the
  points inside it where the gait starts (where the leg is fastened: a servo horn in the
  body). The legs' angles relative to the base are the gait's alone, so this is checked in the
  base frame, sampled every `sample_deg` of the fastest leg's travel.
"""
from __future__ import annotations

import math

import numpy as np

from ..surfaces.raycast import winding_number
from .gaits import GaitError
from .robot import Multibody

SAMPLE_DEG = 2.0
INSIDE = 0.5    # winding number above which a point is inside a closed mesh


def samples(gait, sample_deg: float = SAMPLE_DEG) -> np.ndarray:
    """Instants (s) that sample the gait every sample_deg of its fastest leg, and its knots."""
    ts = [0.0]
    t = 0.0
    while t < gait.duration:
        _, rates = gait.reference(t)
        fastest = float(np.max(np.abs(rates))) if len(rates) else 0.0
        t += min(0.05, math.radians(sample_deg) / fastest) if fastest > 0 else 0.05
        ts.append(min(t, gait.duration))
    return np.unique(np.concatenate([ts, [k for k in gait.knots() if k <= gait.duration]]))


def check_gait(robot: Multibody, gait) -> None:
    """GaitError when the gait drives a joint outside its range or a leg through the body."""
    ts = samples(gait)
    qs = np.array([gait.reference(t)[0] for t in ts])
    for i, leg in enumerate(robot.legs):
        if leg.limits is None:
            continue
        lo, hi = leg.limits
        bad = np.flatnonzero((qs[:, i] < lo - 1e-9) | (qs[:, i] > hi + 1e-9))
        if len(bad):
            k = int(bad[0])
            raise GaitError(f'the gait drives joint {leg.name} to {math.degrees(qs[k, i]):.1f} '
                            f'deg at t = {ts[k]:.2f} s, outside its range '
                            f'{math.degrees(lo):.1f}..{math.degrees(hi):.1f} deg')
    mesh = robot.base_mesh
    if mesh is None:
        return
    lo_b, hi_b = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)

    def inside(pts: np.ndarray) -> np.ndarray:
        near = np.flatnonzero(np.all((pts > lo_b) & (pts < hi_b), axis=1))
        out = np.zeros(len(pts), dtype=bool)
        for j in near:
            out[j] = winding_number(mesh.vertices, mesh.faces, pts[j]) > INSIDE
        return out
    fastened = [inside(robot.leg_points_in_base(i, float(qs[0, i])))
                for i in range(len(robot.legs))]
    for k, t in enumerate(ts):
        for i, leg in enumerate(robot.legs):
            pts = robot.leg_points_in_base(i, float(qs[k, i]))
            for p in pts[inside(pts) & ~fastened[i]]:
                raise GaitError(f'the gait drives leg {leg.name} through the body at '
                                f't = {t:.2f} s (joint at {math.degrees(qs[k, i]):.1f} deg: '
                                f'point {np.round(p * 1e3, 1).tolist()} mm of the base frame '
                                'is inside the base)')
