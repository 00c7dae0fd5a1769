"""Model predictions for one pull test: capacity, slip trajectory, with every method.

Predictors: the four AnchorModel surfaces ('ellipsoid', 'alpha', 'twist-mesh', 'direct') and
'map' (CapacityMap.query on a precomputed HDF5 map). Trajectories use rftgls_core.sim
(quasi-static slip integration, paper section IV) from the measured initial state.

Medium files (JSON, written by calibrate): {"name", "xi_n", "mu_surf", "zeta", ...} with the
fields of rftgls_core.rft.media.Medium; extra keys (covariance, confidence intervals, fit
report) are ignored here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rftgls_core.predictor import Predictor
from rftgls_core.rft.media import Medium, medium_from_dict
from rftgls_core.rft.media import load_medium as core_load_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.surfaces.registry import PREDICTOR_METHODS
from rftgls_core.types import AnchorState

from .bag_layout import PullTest

# Every registered method that is not a reference only, and the shipped map.
METHODS = PREDICTOR_METHODS + ('map',)


def load_medium(spec: str | Path | dict) -> Medium:
    """A preset name, a medium JSON file path, or a dict (rftgls_core.rft.media)."""
    if isinstance(spec, dict):
        return medium_from_dict(spec)
    return core_load_medium(str(spec))


def make_predictor(method: str, robot: str, medium: Medium, map_path: str | Path | None = None,
                   n_twists: int | None = None) -> Predictor:
    """The core Predictor of `method` (one of METHODS) for `robot` in `medium`: the live
    AnchorModel, or for 'map' the CapacityMap at map_path (checked to be of `robot`)."""
    if method == 'map':
        if map_path is None:
            raise ValueError("method 'map' needs a map file")
        from rftgls_core.maps import CapacityMap, resolve_map
        cmap = CapacityMap.load(resolve_map(map_path))   # predict() like AnchorModel
        if cmap.robot_name != robot:
            raise ValueError(f'{cmap.source}: map is for robot {cmap.robot_name!r}, the test '
                             f'is of {robot!r}')
        return cmap
    from rftgls_core.anchor import AnchorModel
    return AnchorModel(get_robot(robot), medium, method=method, n_twists=n_twists)


def initial_pose(test: PullTest) -> np.ndarray | None:
    """Measured (x0, z0, thetaB0) of p: the median of the tracked poses up to the peak pull
    force (the anchor has not slipped yet, so the median beats one noisy frame), or None."""
    if not len(test.pose):
        return None
    t_peak = test.force_t[int(np.argmax(test.tension_N))] if len(test.tension_N) else -np.inf
    still = test.pose[test.pose_t <= t_peak]
    return np.median(still if len(still) else test.pose[:1], axis=0)


def measured_initial_state(test: PullTest) -> AnchorState:
    """[h, thetaB]_0 from the tracked poses before breakaway (the paper starts from the
    measured pose), legs from the median joint angles; metadata where a series is missing."""
    s0 = test.meta.initial_state
    h, tb = s0.h, s0.theta_b
    p0 = initial_pose(test)
    if p0 is not None:
        h, tb = float(p0[1]), float(p0[2])
    l1, l2 = s0.theta_l1, s0.theta_l2
    if len(test.legs):
        l1, l2 = (float(v) for v in np.median(test.legs, axis=0))
    return AnchorState(h, tb, l1, l2)


@dataclass
class PredictedPull:
    """One method's prediction of one test. traj: (K, 5) = s, x, z, thetaB, force (NaN where
    no value) in lab_world from x = x0 of the test; stop_reason as rftgls_core.sim says."""

    method: str
    state: AnchorState
    breakaway_N: float            # capacity at the initial state (NaN when no value)
    slip_twist: tuple | None      # raw unit twist at the initial state
    traj: np.ndarray
    stop_reason: str
    status: str

    @property
    def peak_N(self) -> float:
        f = self.traj[:, 4]
        return float(np.nanmax(f)) if np.isfinite(f).any() else math.nan


def predict_pull(predictor: Predictor, test: PullTest, method: str, step: float = 1e-3,
                 max_travel: float = 0.04, integrator: str = 'heun',
                 state: AnchorState | None = None) -> PredictedPull:
    """Capacity and slip trajectory of `test` (initial state measured unless given)."""
    from rftgls_core.sim.trajectory import simulate_pull

    state = state or measured_initial_state(test)
    meta = test.meta
    robot = get_robot(meta.robot)
    res = predictor.predict(state, meta.phi_rad, meta.pull)
    traj = simulate_pull(predictor, state, meta.phi_rad, meta.pull,
                         lambda st: robot.pose(st, meta.pull).plate_min_z, step=step,
                         integrator=integrator, max_travel=max_travel)
    arr = traj.as_array()
    p0 = initial_pose(test)
    if p0 is not None:
        arr[:, 1] += p0[0]               # the simulation starts at x = 0; the test at x0
    cap = res.capacity_N if res.status.has_value and res.capacity_N is not None else math.nan
    return PredictedPull(method, state, float(cap), res.slip_twist if res.status.has_value
                         else None, arr, traj.stop_reason, res.status.value)
