"""The pose a burrow is modelled to end in, with its band: what the stack sends as the burrowed
height of p (provenance modelled) and holds the measured pitch against after a burrow.

The planner's answer for a gait (bound.GaitAnswer) carries the nominal run's pose and one
sigma of h and theta_b over the spread of the medium and the servo (predict.py, spread.py).
The band is BAND_SIGMAS of those sigmas, the convention of the paper's Table II spreads (mean
+- two standard deviations). A gait whose spread runs failed has no sigma: its band is NaN (not
stated), and capacity_node then takes the height as assumed, never as `ok`.

`mode_pose` answers for one of the paper's modes (DH, DL, SH) from the robot's shipped gait
map for the sled it burrows tied to; `burrowed_pose` for any planned gait's answer. No ROS.
Units SI: m, rad.

Where the robot's burrows of a mode were measured (robots.measured_burrows: MiniRQuad's Table
II), the modelled height's band is widened to cover the measured mean +- BAND_SIGMAS SDs too.
The robot does not measure h, so nothing after the burrow would catch a model that is off in
h (SH: modelled 40 +- 3 mm, measured 47 +- 2 mm): a band that covers both keeps the lower
bound on the side of whichever is right. The pitch band stays the model's: the IMU measures
the pitch after the burrow, and a pitch outside the model's band says the model does not
describe this burrow (pitch_disagreement), which no widening should hide.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..robots.measured_burrows import MeasuredBurrow, measured_burrow
from .bound import GaitAnswer, answer
from .gait_map import GaitMap
from .planner import find_map
from .predict import PlanInputs

BAND_SIGMAS = 2.0
# The confidence answer() is asked at: the pose and its sigma do not depend on it.
_LEVEL = 0.95


@dataclass(frozen=True)
class BurrowedPose:
    """h_m: height of p above the surface; theta_b_rad: body pitch (positive: axle end above
    p); each with its band, the half-width of the range the true value lies in (NaN: not
    stated); source: what gave it, for people."""

    h_m: float
    h_band_m: float
    theta_b_rad: float
    theta_b_band_rad: float
    source: str

    def pitch_disagreement(self, measured_theta_b_rad: float) -> float | None:
        """How far (rad) a measured pitch lies outside the modelled pitch's band; None when it
        lies inside (the burrow went as modelled) or nothing can be said (no band, no
        measurement)."""
        if not (math.isfinite(measured_theta_b_rad) and math.isfinite(self.theta_b_band_rad)
                and math.isfinite(self.theta_b_rad)):
            return None
        off = abs(measured_theta_b_rad - self.theta_b_rad) - self.theta_b_band_rad
        return off if off > 0.0 else None

    def covering_height(self, measured: MeasuredBurrow) -> 'BurrowedPose':
        """This pose with its height band widened to the smallest range that holds both the
        modelled range and the measured mean +- BAND_SIGMAS SDs (centred on that range). A
        band that is not stated stays not stated."""
        if not math.isfinite(self.h_band_m):
            return self
        half = BAND_SIGMAS * measured.h_sd_m
        lo = min(self.h_m - self.h_band_m, measured.h_m - half)
        hi = max(self.h_m + self.h_band_m, measured.h_m + half)
        return replace(self, h_m=0.5 * (lo + hi), h_band_m=0.5 * (hi - lo),
                       source=f'{self.source}; height band widened to cover '
                              f'{1e3 * measured.h_m:.0f} +- {1e3 * half:.0f} mm measured '
                              f'({measured.source})')


def burrowed_pose(gait_answer: GaitAnswer, source: str) -> BurrowedPose | None:
    """The modelled burrowed pose of a gait's answer; None when its nominal run has no pose
    (overturned, out of its step budget, not runnable)."""
    pose, sigma = gait_answer.pose, gait_answer.pose_sigma
    h, theta_b = float(pose[0]), float(pose[1])
    if not (math.isfinite(h) and math.isfinite(theta_b)):
        return None
    h_sig, tb_sig = float(sigma[0]), float(sigma[1])
    return BurrowedPose(h, BAND_SIGMAS * h_sig, theta_b, BAND_SIGMAS * tb_sig, source)


def preset_inputs(robot: str, sled_kg: float, phis: tuple[float, ...] = (0.0,)) -> PlanInputs:
    """The plan inputs of a robot preset in its own medium with the assumed spread (what
    `rftgls plan burrow --robot ROBOT --sled KG` uses)."""
    from ..predictor.spec import ROBOT_MEDIUM
    from ..rft.media import load_medium, medium_covariance
    from .spread import Spread
    medium = load_medium(ROBOT_MEDIUM[robot])
    cov, cov_source = medium_covariance(None, medium.xi_n)
    return PlanInputs(robot, medium, Spread.of(cov, cov_source), tuple(phis),
                      sled_kg=float(sled_kg))


def mode_pose(mode: str, sled_kg: float, robot: str = 'minirquad',
              gait_map: GaitMap | None = None) -> BurrowedPose | None:
    """The modelled burrowed pose of one of the paper's modes (DH, DL, SH) for the sled the
    robot burrows tied to (kg), from the robot's shipped gait map (or `gait_map`). ValueError
    when no map answers for these inputs (a live simulation takes minutes: not onboard) or the
    map has no such mode; None when the mode's nominal run has no pose. Where this mode was
    measured on the robot, the height band covers the measurement too (covering_height)."""
    if gait_map is None:
        gait_map, why = find_map(preset_inputs(robot, sled_kg), None)
        if gait_map is None:
            raise ValueError(f'no modelled pose for {mode} with a {sled_kg:g} kg sled: {why}')
        where = why
    else:
        where = 'the given gait map'
    gaits = gait_map.gaits()
    names = [g.name for g in gaits]
    if mode not in names:
        raise ValueError(f'the gait map has no mode {mode!r} (it has '
                         f'{", ".join(n for n in names if n)})')
    k = names.index(mode)
    runs = gait_map.runs([float(gait_map.phis[0])])[k]
    pose = burrowed_pose(answer(gaits[k], runs, _LEVEL),
                         f'burrow simulation of {mode}, sled {1e3 * sled_kg:.0f} g ({where})')
    measured = measured_burrow(robot, mode)
    return pose if pose is None or measured is None else pose.covering_height(measured)
