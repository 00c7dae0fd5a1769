"""One gait's answer from its runs (predict.py): the predicted pose, its electrical energy,
the capacity over the tether angles asked and its lower bound at a confidence.

For each tether angle phi, with C_0 the nominal run's capacity and (C_+i, C_-i) the runs one
sigma to either side along input i (linear propagation, central differences):

    sigma_C^2 = sum_i ((C_+i - C_-i) / 2)^2
    lower     = max(0, min(C_0 - z sigma_C, min over all runs of C))

z is the one-sided normal quantile of the confidence. The minimum over the runs keeps the
bound honest where the response is not linear (a capacity that falls on both sides of the
nominal, or a bistable burrow): one sigma lies inside any band of 68 % or more, so no run's
capacity can sit below a bound that claims that confidence. A run without a pose (overturned,
unsupported, out of its step budget) or a capacity without a value makes the gait no
candidate: its lower bound is 0 and its status names the run.

Over several tether angles the gait's lower bound is the smallest of them, and its capacity
the smallest nominal one: a tug passes through every angle asked.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from ..types import Status
from .gaits import GaitPoint
from .predict import GaitRuns


@dataclass
class GaitAnswer:
    """A gait and what the planner predicts for it. status: 'assumed' (a value from assumed
    inputs) or why not (the status of the run or capacity that failed); reason: one line.
    pose: nominal (h m, theta_b, theta_l1, theta_l2 rad); pose_sigma: (h m, theta_b rad) one
    sigma over the spread. capacity_N, lower_bound_N: the smallest over phi (None without a
    value); per_phi: [(capacity_N, sigma_N, lower_N)] per tether angle; energy_elec_J: the
    nominal run's electrical energy above standby."""

    gait: GaitPoint
    status: str
    reason: str
    pose: np.ndarray
    pose_sigma: np.ndarray
    energy_elec_J: float | None
    capacity_N: float | None
    lower_bound_N: float | None
    per_phi: list[tuple[float, float, float]]

    @property
    def candidate(self) -> bool:
        return Status(self.status).has_value and self.lower_bound_N is not None

    def to_json(self, phis: tuple[float, ...]) -> dict:
        d = self.gait.to_json()
        has_pose = bool(np.isfinite(self.pose).all())
        d['pose'] = ({'h_m': float(self.pose[0]), 'theta_b_deg': math.degrees(self.pose[1]),
                      'theta_l1_deg': math.degrees(self.pose[2]),
                      'theta_l2_deg': math.degrees(self.pose[3]),
                      'h_sigma_m': _num(float(self.pose_sigma[0])),
                      'theta_b_sigma_deg': _num(math.degrees(self.pose_sigma[1])),
                      'provenance': 'modelled'} if has_pose else None)
        d['lower_bound_N'] = self.lower_bound_N
        d['capacity_N'] = self.capacity_N
        d['energy_elec_J'] = self.energy_elec_J
        d['status'] = self.status
        d['reason'] = self.reason
        d['per_phi'] = [{'phi_deg': math.degrees(p), 'capacity_N': _num(c), 'sigma_N': _num(s),
                         'lower_bound_N': _num(lo)}
                        for p, (c, s, lo) in zip(phis, self.per_phi)]
        return d


def _num(v: float) -> float | None:
    """JSON has no NaN: a value that is not there is null."""
    return float(v) if math.isfinite(v) else None


def z_of(level: float) -> float:
    if not (math.isfinite(level) and 0.5 <= level < 1.0):
        raise ValueError(f'confidence must be in [0.5, 1), got {level}')
    return NormalDist().inv_cdf(level)


def answer(gait: GaitPoint, runs: GaitRuns, level: float) -> GaitAnswer:
    """The gait's answer at one-sided confidence `level` (module doc)."""
    z = z_of(level)
    pose0 = runs.pose[0]
    nan2 = np.full(2, np.nan)
    if runs.runnable is not None:
        return GaitAnswer(gait, Status.INVALID_INPUT.value, f'not_runnable: {runs.runnable}',
                          pose0, nan2, None, None, None, [])
    for i, st in enumerate(runs.status):
        if st != 'not_run' and not Status(st).has_value:
            return GaitAnswer(gait, st, f'{runs.reason[i]} ({runs.labels[i]} run)', pose0,
                              nan2, _energy(runs), None, None, [])
    sig = np.zeros(2)
    for a, b in runs.pairs:
        sig += (0.5 * (runs.pose[a, :2] - runs.pose[b, :2])) ** 2
    sig = np.sqrt(sig)
    per_phi = []
    failed: tuple[str, str] | None = None      # (status, reason) of the first capacity lost
    for k in range(runs.capacity_N.shape[1]):
        c = runs.capacity_N[:, k]
        if not np.isfinite(c).all():
            i = int(np.flatnonzero(~np.isfinite(c))[0])
            if failed is None:
                why = runs.cap_reason[i][k]
                failed = (why.split(':')[0], f'capacity {why} at phi '
                          f'{math.degrees(_phi(runs, k)):.1f} deg ({runs.labels[i]} run)')
            per_phi.append((float(c[0]) if np.isfinite(c[0]) else math.nan, math.nan, 0.0))
            continue
        var = sum((0.5 * (c[a] - c[b])) ** 2 for a, b in runs.pairs)
        s = math.sqrt(var)
        lower = max(0.0, min(float(c[0]) - z * s, float(c.min())))
        per_phi.append((float(c[0]), s, lower))
    if failed is not None:
        return GaitAnswer(gait, failed[0], failed[1], pose0, sig, _energy(runs), None, None,
                          per_phi)
    cap = min(p[0] for p in per_phi)
    lower = min(p[2] for p in per_phi)
    return GaitAnswer(gait, Status.ASSUMED.value, 'assumed inputs: the medium preset or '
                      'calibration, the servo tolerance, robot geometry and sled '
                      '(docs/design/burrow-planner.md)', pose0, sig, _energy(runs), cap, lower,
                      per_phi)


def _phi(runs: GaitRuns, k: int) -> float:
    return runs.phis[k]


def _energy(runs: GaitRuns) -> float | None:
    e = runs.energy_elec_J[0]
    return float(e) if np.isfinite(e) else None
