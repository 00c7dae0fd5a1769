"""One gait, predicted: the burrow simulated over the spread (spread.py), and the capacity at
the pose each run ends in, for every tether angle asked.

`PlanInputs` is everything that defines the answers (robot, pull, medium and its spread, the
sled the robot is tied to while it burrows, the tether angles, the simulation's options and
step budget, the capacity method); `inputs_sha256` identifies it, so a gait map answers only
for the inputs it was built from. `predict_gait` is a pure function of (inputs, gait): the
live planner and the map build call the same one.
"""
from __future__ import annotations

import hashlib
import json
import math
import threading
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..multibody.robot import Multibody
from ..multibody.servo import XL330_M077_5V
from ..multibody.simulate import SimOptions, SimulationStop, Simulator
from ..rft.media import Medium
from ..types import AnchorState, Status
from .gaits import GaitPoint, why_not_runnable
from .spread import Spread, runs, servo_line_binds

# A run that needs more steps than this is not resolved (a fall or a slide the step control
# follows in sub-millimetre steps: one tethered deep burrow took ~10,000 steps and 100 s).
# It is reported `degenerate`, `step_budget` and is never a candidate. Steps, not seconds:
# the same inputs give the same answer on any machine.
STEP_BUDGET = 2500
POSE_KEYS = ('h', 'theta_b', 'theta_l1', 'theta_l2')


@dataclass(frozen=True)
class PlanInputs:
    """robot: preset name ('minirquad', 'prototype') or the path of a description YAML
    (anchor=True). pull: C-leg orientation. medium: the nominal medium; spread: its covariance
    and the servo tolerance. sled_kg: the sled the robot is tied to while it burrows (0: no
    rope). phis: tether angles, rad. options: the simulation's step control. step_budget: most
    steps per run. method, n_twists, model: the capacity predictor (build_predictor)."""

    robot: str
    medium: Medium
    spread: Spread
    phis: tuple[float, ...]
    sled_kg: float = 0.0
    pull: str = 'backward'
    anchor: bool = False
    options: SimOptions = field(default_factory=SimOptions)
    step_budget: int = STEP_BUDGET
    method: str = 'twist-mesh'
    n_twists: int | None = None
    model: str = 'agarwal'

    def __post_init__(self) -> None:
        if not self.phis or not all(math.isfinite(p) for p in self.phis):
            raise ValueError('give at least one finite tether angle')
        if not (math.isfinite(self.sled_kg) and self.sled_kg >= 0.0):
            raise ValueError(f'sled mass must be >= 0 kg, got {self.sled_kg}')
        if self.step_budget < 1:
            raise ValueError('step budget must be >= 1')

    def multibody(self) -> Multibody:
        return _multibody(self.robot, self.anchor, self.pull)

    def identity(self) -> dict:
        """What defines the answers (JSON-able; the tether angles left out: a map holds its
        own and answers the ones it has)."""
        return {'robot': self.multibody().describe(), 'geometry_sha256': _geometry_hash(
                    self.multibody()), 'pull': self.pull, 'medium': self.medium.to_dict(),
                'spread': self.spread.describe(), 'sled_kg': self.sled_kg,
                'servo': XL330_M077_5V.describe(),
                'options': {k: getattr(self.options, k)
                            for k in self.options.__dataclass_fields__},
                'step_budget': self.step_budget, 'method': self.method,
                'n_twists': self.n_twists, 'model': self.model}

    def inputs_sha256(self) -> str:
        text = json.dumps(self.identity(), sort_keys=True, default=str)
        return hashlib.sha256(b'rftgls.burrow_plan_inputs/1\0' + text.encode()).hexdigest()


@lru_cache(maxsize=4)
def _multibody(robot: str, anchor: bool, pull: str) -> Multibody:
    from ..multibody.robot import from_preset
    from ..robots.presets import get_robot
    if anchor:
        from ..description import load_description
        from ..multibody.described import from_description
        return from_description(load_description(robot), pull)
    return from_preset(get_robot(robot), pull)


def _geometry_hash(robot: Multibody) -> str:
    h = hashlib.sha256()
    parts = ([robot.base] if robot.base is not None else []) + [leg.facets for leg in robot.legs]
    for f in parts:
        for a in (f.centroids, f.normals, f.areas):
            h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    for leg in robot.legs:
        h.update(np.asarray([*leg.hip, *leg.axis_base], dtype=np.float64).tobytes())
    h.update(np.asarray([robot.mass, *robot.com, *robot.tether], dtype=np.float64).tobytes())
    return h.hexdigest()


@dataclass
class GaitRuns:
    """Every run of one gait (R runs, K tether angles). status/reason per run ('' reason when
    it has a value); pose (R, 4): h m, theta_b, theta_l1, theta_l2 rad at the end (NaN without
    a value); energy_elec_J (R,): electrical energy above standby; capacity_N (R, K): NaN
    where the capacity has no value, cap_reason (R, K) its status and reason; pairs: the run
    index pairs (+, -) of each input; runnable: None or why the robot cannot run the gait;
    steps: steps simulated per run."""

    status: list[str]
    reason: list[str]
    pose: np.ndarray
    energy_elec_J: np.ndarray
    capacity_N: np.ndarray
    cap_reason: list[list[str]]
    pairs: list[tuple[int, int]]
    labels: list[str]
    phis: tuple[float, ...]
    runnable: str | None = None
    steps: list[int] = field(default_factory=list)


def predict_gait(inputs: PlanInputs, gait: GaitPoint, progress=None) -> GaitRuns:
    """Simulate `gait` over the spread and predict the capacity at each run's pose."""
    robot = inputs.multibody()
    plan_runs = runs(inputs.spread, inputs.medium, XL330_M077_5V)
    R, K = len(plan_runs), len(inputs.phis)
    out = GaitRuns(['invalid_input'] * R, [''] * R, np.full((R, 4), np.nan), np.full(R, np.nan),
                   np.full((R, K), np.nan), [[''] * K for _ in range(R)], _pairs(plan_runs),
                   [r.label for r in plan_runs], tuple(inputs.phis), steps=[0] * R)
    why = why_not_runnable(robot, gait)
    if why is not None:
        out.runnable = why
        out.reason = ['not_runnable'] * R
        return out
    nominal = None
    for i, run in enumerate(plan_runs):
        if i > 0 and not np.isfinite(out.pose[:i, 0]).all():
            # a run without a pose already rules the gait out: the rest are not simulated
            out.status[i], out.reason[i] = 'not_run', 'an_earlier_run_failed'
            continue
        if run.servo_pair and nominal is not None and not servo_line_binds(
                nominal.samples, XL330_M077_5V.scaled(1.0 - inputs.spread.stall_rel_sigma)):
            _copy_run(out, 0, i)            # the servo's line never bound: the same run
            continue
        res = simulate_burrow(inputs, robot, gait.burrow(robot), run)
        if i == 0:
            nominal = res
        out.steps[i] = len(res.samples)
        out.status[i] = res.status.value
        out.reason[i] = '' if res.ok else res.reason
        if res.ok:
            last = res.samples[-1]
            q = res.final_dofs()
            out.pose[i] = (last.z, last.theta_b, q[0], q[1] if len(q) > 1 else np.nan)
            assert res.meter is not None
            out.energy_elec_J[i] = res.meter.total().elec_J
            _capacities(inputs, run.medium, out, i)
        if progress:
            progress()
    return out


def _pairs(plan_runs) -> list[tuple[int, int]]:
    by: dict[int, list[int]] = {}
    for i, r in enumerate(plan_runs):
        if r.pair >= 0:
            by.setdefault(r.pair, []).append(i)
    return [(v[0], v[1]) for _, v in sorted(by.items())]


def _copy_run(out: GaitRuns, src: int, dst: int) -> None:
    out.status[dst], out.reason[dst] = out.status[src], out.reason[src]
    out.pose[dst], out.energy_elec_J[dst] = out.pose[src], out.energy_elec_J[src]
    out.capacity_N[dst] = out.capacity_N[src]
    out.cap_reason[dst] = list(out.cap_reason[src])
    out.steps[dst] = 0


def simulate_burrow(inputs: PlanInputs, robot: Multibody, gait, run):
    """One run of a burrow (a multibody gait: BurrowGait, ReplayGait) on these inputs: the
    run's medium and servo, the sled, the step control and its budget."""
    from ..multibody.sled import Sled
    sled = Sled(inputs.sled_kg) if inputs.sled_kg > 0.0 else None
    sim = Simulator(robot, run.medium, run.servo, inputs.options, model=inputs.model, sled=sled)

    def budget(_t: float) -> None:
        if len(sim.samples) > inputs.step_budget:
            raise SimulationStop(Status.DEGENERATE, 'step_budget',
                                 f'more than {inputs.step_budget} steps by t = {sim.t:.2f} s '
                                 '(a fall or slide followed in sub-millimetre steps)')
    return sim.run(gait, progress=budget)


def _capacities(inputs: PlanInputs, medium: Medium, out: GaitRuns, i: int) -> None:
    predictor = _predictor(inputs.robot, inputs.anchor, inputs.pull, medium, inputs.method,
                           inputs.n_twists, inputs.model)
    h, tb, l1, l2 = (float(v) for v in out.pose[i])
    state = AnchorState(h, tb, l1, 0.0 if math.isnan(l2) else l2)
    for k, phi in enumerate(inputs.phis):
        r = predictor.predict(state, phi, inputs.pull)
        if r.status.has_value and r.capacity_N is not None:
            out.capacity_N[i, k] = float(r.capacity_N)
            out.cap_reason[i][k] = ''
        else:
            out.cap_reason[i][k] = f'{r.status.value}: {r.reason}' if r.reason else \
                r.status.value


_local = threading.local()   # per thread (Dask runs tasks on threads), per process


def _predictor(robot: str, anchor: bool, pull: str, medium: Medium, method: str,
               n_twists: int | None, model: str):
    """The one predictor builder's live predictor for this medium (kept per process: each
    worker builds its own)."""
    from ..predictor import PredictorSpec, build_predictor
    cache = getattr(_local, 'predictors', None)
    if cache is None:
        cache = _local.predictors = {}
    key = (robot, anchor, pull, medium, method, n_twists, model)
    if key not in cache:
        spec = (PredictorSpec(robot=None, description=robot, medium=medium, live_method=method,
                              n_twists=n_twists, model=model, pull=pull) if anchor else
                PredictorSpec(robot=robot, medium=medium, live_method=method,
                              n_twists=n_twists, model=model, pull=pull))
        cache[key] = build_predictor(spec)
        if len(cache) > 16:
            cache.pop(next(iter(cache)))
    return cache[key]
