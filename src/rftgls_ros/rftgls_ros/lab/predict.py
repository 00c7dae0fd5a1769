"""Model predictions for one pull test: capacity, slip trajectory, with every method.

Predictors (rftgls_core.predictor.build_predictor): the live solver with one of the four
surface methods ('ellipsoid', 'alpha', 'twist-mesh', 'direct') and 'map' (a precomputed HDF5
map). Trajectories use rftgls_core.sim (quasi-static slip integration, paper section IV) from
the measured initial state.

Robot: the bag's (metadata `robot`, a preset name) unless an anchor description is given
(`--anchor FILE.yaml` of evaluate and calibrate; rftgls_core.description): then the
description is posed from the measured (h, thetaB, thetaL1, thetaL2), fed to its state
variables by name or by `--anchor-state NAME=QUANTITY,...` (as capacity_node's
anchor_state_variables; load_anchor checks; ValueError, one line), and a slip stops
where the description's `surface_points` reach the surface. For the shipped description of
the bag's robot this gives the preset's numbers (tests/lab/test_lab_anchor.py).

Medium files (JSON, written by calibrate): {"name", "xi_n", "mu_surf", "zeta", ...} with the
fields of rftgls_core.rft.media.Medium; extra keys (covariance, confidence intervals, fit
report) are ignored here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rftgls_core.description import (
    AnchorDescription,
    DescriptionError,
    load_description,
    parse_state_map,
    robot_state_map,
    state_values,
)
from rftgls_core.predictor import InputNames, Predictor, PredictorSpec, build_predictor
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


@dataclass(frozen=True)
class LabAnchor:
    """An anchor description as the lab tools pose it: state_map says which measured
    quantity (h, theta_b, theta_l1, theta_l2) feeds each of its state variables."""

    description: AnchorDescription
    state_map: dict[str, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.description.name

    @property
    def sha256(self) -> str:
        return self.description.sha256

    def values(self, state: AnchorState) -> dict[str, float]:
        """The description's state values (SI) of a measured AnchorState."""
        robot = state_values(state)
        return {n: robot[q] for n, q in self.state_map.items()}


def load_anchor(path: str | Path | None, state: str = '') -> LabAnchor | None:
    """The description of `--anchor` (None: the bags' own robot), its variables fed by name
    or by `state` ('NAME=QUANTITY,...', --anchor-state). ValueError (one line) when it
    cannot be read or a variable is fed by nothing a bag measures (h, thetaB and the two leg
    angles)."""
    if path is None or not str(path).strip():
        if state.strip():
            raise ValueError('--anchor-state needs --anchor')
        return None
    try:
        desc = load_description(path)
    except DescriptionError as exc:
        raise ValueError(f'--anchor: {" ".join(str(exc).split())}') from None
    try:
        mapping = robot_state_map(desc, parse_state_map(state))
    except DescriptionError as exc:
        raise ValueError(f'--anchor: {" ".join(str(exc).split())} (what a pull-test bag '
                         'measures; --anchor-state NAME=QUANTITY,... maps them)') from None
    return LabAnchor(desc, mapping)


def add_anchor_arguments(ap) -> None:
    """--anchor and --anchor-state of the lab tools (argparse)."""
    ap.add_argument('--anchor', default=None, metavar='FILE.yaml',
                    help="anchor description (YAML with its URDF) to pose instead of the bags' "
                         'robot; its state variables are fed from h, theta_b, theta_l1, '
                         'theta_l2 by name or by --anchor-state')
    ap.add_argument('--anchor-state', default='', metavar='NAME=QUANTITY,...',
                    help='which measured quantity feeds each state variable of --anchor, e.g. '
                         'depth=h,tilt=theta_b')


# The lab tools' option for each input of a predictor specification (errors name these).
LAB_NAMES = InputNames(
    map='--map', robot="the test's robot", description='--anchor', state_map='--anchor-state',
    medium='the medium', live_method='--method', n_twists='--twists', verb='give',
    state_source='what a pull-test bag measures; --anchor-state NAME=QUANTITY,... maps them')


def make_predictor(method: str, robot: str, medium: Medium, map_path: str | Path | None = None,
                   n_twists: int | None = None,
                   anchor: LabAnchor | None = None) -> Predictor:
    """The core Predictor of `method` (one of METHODS) for `robot` in `medium`, built by
    rftgls_core.predictor.build_predictor: the live solver, or for 'map' the map at map_path
    (checked to be of `robot`). anchor: a description to pose instead of the preset `robot`
    (a map must then answer for that description). ValueError (one line) otherwise."""
    described = {} if anchor is None else {'description': anchor.description,
                                           'state_map': anchor.state_map}
    if method == 'map':
        if map_path is None:
            raise ValueError("method 'map' needs a map file")
        spec = PredictorSpec(map=str(map_path), robot=None if anchor else robot, **described)
    else:
        spec = PredictorSpec(robot=robot, medium=medium, live_method=method, n_twists=n_twists,
                             **described)
    return build_predictor(spec, LAB_NAMES)


def surface_min_z(robot: str, pull: str, anchor: LabAnchor | None = None):
    """plate_min_z(state) for rftgls_core.sim.simulate_pull: the preset's body plate, or the
    description's surface_points (m; the run stops when it reaches 0)."""
    if anchor is not None:
        desc = anchor.description
        return lambda st: desc.surface_min_z(anchor.values(st))
    rb = get_robot(robot)
    return lambda st: rb.pose(st, pull).plate_min_z


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
                 state: AnchorState | None = None,
                 anchor: LabAnchor | None = None) -> PredictedPull:
    """Capacity and slip trajectory of `test` (initial state measured unless given); anchor:
    the description posed instead of the bag's robot (its surface_points end the slip)."""
    from rftgls_core.sim.trajectory import simulate_pull

    state = state or measured_initial_state(test)
    meta = test.meta
    res = predictor.predict(state, meta.phi_rad, meta.pull)
    traj = simulate_pull(predictor, state, meta.phi_rad, meta.pull,
                         surface_min_z(meta.robot, meta.pull, anchor), step=step,
                         integrator=integrator, max_travel=max_travel)
    arr = traj.as_array()
    p0 = initial_pose(test)
    if p0 is not None:
        arr[:, 1] += p0[0]               # the simulation starts at x = 0; the test at x0
    cap = res.capacity_N if res.status.has_value and res.capacity_N is not None else math.nan
    return PredictedPull(method, state, float(cap), res.slip_twist if res.status.has_value
                         else None, arr, traj.stop_reason, res.status.value)
