"""Where the scripted body settles after a burrow run leg by leg (SetLegs): the pose the
burrow simulation predicts for that gait, read from the gait map of the simulator's sled.

The scripted body has no sand mechanics of its own: after a Table II burrow it settles at
Table II's mean pose (burrow.py), and after a gait run with SetLegs (a host streaming a
planned gait's ramp) at the nominal pose rftgls_core's burrow simulation predicts for the gait
in the gait map (the same prediction the stack plans with: with the scripted body a test
checks the stack's handling of a planned gait, not the pose model). The gait is known by its
retracting pose (the most retracted legs since the robot last stood or walked: every gait of
the gait space retracts at least as far as it ends) and its final pose (the legs' target);
a pose within MATCH_RAD of a map gait on every angle counts as that gait, anything else leaves
the body where it is. Angles in rad, h in m.
"""
from __future__ import annotations

import math

import numpy as np

MATCH_RAD = math.radians(1.0)


class GaitPoses:
    """(retract, final) -> (h, theta_b) of the gait map's gaits (nominal runs)."""

    def __init__(self, gaits: np.ndarray, poses: np.ndarray):
        self.gaits = np.asarray(gaits, dtype=float)[:, :4]   # retract l1, l2, final l1, l2
        self.poses = np.asarray(poses, dtype=float)          # (N, 2): h, theta_b

    @classmethod
    def for_sled(cls, sled_kg: float, robot: str = 'minirquad') -> GaitPoses | None:
        """From the shipped gait map built for this sled (kg); None without one."""
        from rftgls_core.planning.gait_map import for_sled, shipped_paths
        gmap, _ = for_sled(sled_kg, shipped_paths(robot))
        if gmap is None:
            return None
        pose = gmap.arrays['pose'][:, 0, :2]       # the nominal run of every gait
        ok = np.isfinite(pose).all(axis=1)
        return cls(gmap.arrays['gaits'][ok], pose[ok])

    def pose(self, retract: tuple[float, float],
             final: tuple[float, float]) -> tuple[float, float] | None:
        """(h m, theta_b rad) of the gait (retract, final), None when no map gait matches."""
        d = np.abs(self.gaits - np.array([*retract, *final])).max(axis=1)
        i = int(np.argmin(d))
        if d[i] > MATCH_RAD:
            return None
        return float(self.poses[i, 0]), float(self.poses[i, 1])
