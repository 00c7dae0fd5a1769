"""The burrowed pose estimated from the burrow as it went: the burrow simulation run over the
leg angles measured during the burrow, instead of the gait that was commanded.

A planned gait's pose (burrowed.py) is what the simulation predicts for the commanded leg
motion. The legs the robot actually moved can differ: a servo that lagged, a leg the sand
held back, a burrow that ended early. `replay_burrow` drives the same simulation (the plan's
inputs: robot, medium, servo, sled, step control; the nominal run of the spread) along the
measured angles, and answers the pose it ends in, with the plan's band (the spread of the
medium and the servo is the same whatever the legs did) and the height of p and x of the
winch point. The measured pitch is then held against the replayed one (pitch_disagreement).

Pure function of (inputs, record): no ROS. Units SI: s, m, rad.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from ..multibody.gaits import BURROW_WINDOW, GaitError, ReplayGait
from ..multibody.servo import XL330_M077_5V
from ..multibody.validate import check_gait
from .burrowed import BurrowedPose, preset_inputs
from .gait_map import GaitMap
from .gaits import STAND
from .predict import PlanInputs, simulate_burrow
from .spread import runs

MIN_SAMPLES = 10          # fewer samples than this do not describe a burrow


@dataclass(frozen=True)
class BurrowRecord:
    """The leg angles measured during one burrow. times: s from the burrow's start, strictly
    increasing; dofs: (theta_L1, theta_L2) per time, rad (each axle's mean of left and
    right)."""

    times: tuple[float, ...]
    dofs: tuple[tuple[float, float], ...]

    @classmethod
    def of(cls, samples) -> BurrowRecord:
        """From (t, theta_l1, theta_l2) samples in any clock (s): times from the first, later
        samples at a repeated or earlier time dropped."""
        ts: list[float] = []
        qs: list[tuple[float, float]] = []
        t0 = 0.0
        for t, a, b in samples:
            if not ts:
                t0 = t
            elif t - t0 <= ts[-1]:
                continue
            ts.append(float(t - t0))
            qs.append((float(a), float(b)))
        return cls(tuple(ts), tuple(qs))

    @classmethod
    def from_standing(cls, samples, stand: tuple[float, float] = STAND) -> BurrowRecord:
        """`of` the samples from the one whose legs came nearest the standing pose (largest
        axle difference): where a planned burrow proper starts, as the plan simulated it."""
        samples = list(samples)
        k = min(range(len(samples)), default=0, key=lambda i: max(
            abs(samples[i][1] - stand[0]), abs(samples[i][2] - stand[1])))
        return cls.of(samples[k:])


@dataclass(frozen=True)
class ReplayedBurrow:
    """pose: the replayed pose with the plan's band (None without one); x_m: x of p, the
    winch point, at the end (m, world, from where the robot was put down; NaN without a
    pose); reason: why there is no pose ('' with one); samples: how many were replayed;
    steps: simulation steps."""

    pose: BurrowedPose | None
    x_m: float
    reason: str
    samples: int
    steps: int = 0


def replay_burrow(inputs: PlanInputs, record: BurrowRecord,
                  plan_pose: BurrowedPose) -> ReplayedBurrow:
    """The pose the burrow simulation ends in when its legs follow `record`, banded like the
    plan's pose `plan_pose`. A record that cannot be replayed (too short, not finite, a leg
    outside its range or through the body) or a run without a final pose gives no pose and
    the reason."""
    n = len(record.times)
    if n < MIN_SAMPLES:
        return ReplayedBurrow(None, math.nan, f'too_few_samples: {n} < {MIN_SAMPLES}', n)
    robot = inputs.multibody()
    try:
        gait = ReplayGait(robot, record.times, record.dofs,
                          duration=max(BURROW_WINDOW, record.times[-1]))
        check_gait(robot, gait)
    except GaitError as exc:
        return ReplayedBurrow(None, math.nan, f'not_runnable: {exc}', n)
    nominal = runs(inputs.spread, inputs.medium, XL330_M077_5V)[0]
    res = simulate_burrow(inputs, robot, gait, nominal)
    if not res.ok:
        return ReplayedBurrow(None, math.nan, f'{res.status.value}: {res.reason}', n,
                              len(res.samples))
    last = res.samples[-1]
    if not (np.isfinite(last.z) and np.isfinite(last.theta_b)):
        return ReplayedBurrow(None, math.nan, 'no_final_pose', n, len(res.samples))
    pose = BurrowedPose(float(last.z), plan_pose.h_band_m, float(last.theta_b),
                        plan_pose.theta_b_band_rad,
                        f'burrow simulation over the {n} measured leg samples '
                        f'(band of {plan_pose.source})')
    return ReplayedBurrow(pose, float(last.x), '', n, len(res.samples))


def inputs_for_map(gait_map: GaitMap, robot: str) -> PlanInputs:
    """The plan inputs a robot preset's gait map was built from (its sled, its tether angles),
    so a replay simulates what the map's predictions simulated. ValueError when the preset's
    inputs today are not the map's (the map would answer for another robot or medium)."""
    sled_kg = float(json.loads(str(gait_map.attrs['inputs_json']))['sled_kg'])
    inputs = preset_inputs(robot, sled_kg, tuple(float(p) for p in gait_map.phis))
    why = gait_map.answers_for(inputs)
    if why is not None:
        raise ValueError(f'cannot replay burrows on this gait map: {why}')
    return inputs
