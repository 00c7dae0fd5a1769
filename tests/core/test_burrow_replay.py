"""The burrowed pose simulated over measured legs (rftgls_core.planning.replay).

Reference: the shipped 400 g gait map's nominal pose of the gait (-40, -20) -> (-40, -20)
deg, built by the planner's own simulation of the commanded ramps (BurrowGait), not by the
replay code."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.multibody.gaits import GaitError, ReplayGait
from rftgls_core.planning.burrowed import burrowed_pose
from rftgls_core.planning.gait_map import for_sled, shipped_paths
from rftgls_core.planning.planner import plan_from_map
from rftgls_core.planning.replay import BurrowRecord, inputs_for_map, replay_burrow

R = math.radians


@pytest.fixture(scope='module')
def planned():
    gmap, _ = for_sled(0.4, shipped_paths('minirquad'))
    inputs = inputs_for_map(gmap, 'minirquad')
    a = next(a for a in plan_from_map(gmap, tuple(gmap.phis), 0.0, 0.95).answers
             if a.gait.same_motion(a.gait.__class__((R(-40), R(-20)), (R(-40), R(-20)),
                                                    a.gait.speed)))
    return inputs, a, burrowed_pose(a, 'plan')


def _record(inputs, gait, dt=0.05, scale=1.0, until=5.0):
    g = gait.burrow(inputs.multibody())
    return BurrowRecord.of([(t, *(scale * g.dof_reference(t)[0]))
                            for t in np.arange(0.0, until, dt)])


def test_replaying_the_commanded_legs_lands_on_the_plans_pose(planned):
    inputs, answer, plan = planned
    r = replay_burrow(inputs, _record(inputs, answer.gait), plan)
    assert r.reason == '' and r.pose is not None and r.samples == 100
    # The replay follows the ramps linearly between 50 ms samples: it differs from them only
    # within 25 ms of their four corners (at most 1.4 deg of leg travel rounded off). Measured
    # 0.01 mm and 0.03 deg; held to a quarter of the plan's own 2-sigma band.
    assert r.pose.h_m == pytest.approx(answer.pose[0], abs=plan.h_band_m / 4)
    assert r.pose.theta_b_rad == pytest.approx(answer.pose[1], abs=plan.theta_b_band_rad / 4)
    assert (r.pose.h_band_m, r.pose.theta_b_band_rad) == (plan.h_band_m, plan.theta_b_band_rad)
    assert math.isfinite(r.x_m) and 'measured leg samples' in r.pose.source


def test_legs_that_fell_short_end_shallower(planned):
    inputs, answer, plan = planned
    short = replay_burrow(inputs, _record(inputs, answer.gait, scale=0.8), plan)
    assert short.pose is not None
    assert short.pose.h_m > answer.pose[0] + plan.h_band_m     # outside the plan's band


def test_records_that_cannot_be_replayed_say_why(planned):
    inputs, answer, plan = planned
    few = replay_burrow(inputs, _record(inputs, answer.gait, until=0.2), plan)
    assert few.pose is None and few.reason.startswith('too_few_samples')
    rec = _record(inputs, answer.gait)
    lost = BurrowRecord(rec.times, rec.dofs[:50] + ((math.nan, 0.0),) + rec.dofs[51:])
    bad = replay_burrow(inputs, lost, plan)     # a sample the encoder did not give
    assert bad.pose is None and bad.reason.startswith('not_runnable'), bad.reason
    assert 'finite' in bad.reason


def test_a_record_keeps_only_increasing_times_and_a_replay_gait_checks_its_rows(planned):
    rec = BurrowRecord.of([(10.0, 0.0, 0.0), (10.1, -0.1, 0.0), (10.1, -0.2, 0.0),
                           (10.05, -0.3, 0.0), (10.3, -0.4, 0.0)])
    assert rec.times == pytest.approx((0.0, 0.1, 0.3)) and rec.dofs[-1] == (-0.4, 0.0)
    walked = BurrowRecord.from_standing([(0.0, -1.0, -1.0), (0.1, -0.5, -0.6),
                                         (0.2, 0.01, -0.02), (0.3, -0.2, -0.1)])
    assert walked.times == pytest.approx((0.0, 0.1)) and walked.dofs[0] == (0.01, -0.02)
    robot = planned[0].multibody()
    with pytest.raises(GaitError, match='at least two'):
        ReplayGait(robot, (0.0,), ((0.0, 0.0),), 8.0)
    with pytest.raises(GaitError, match='finite'):
        ReplayGait(robot, (0.0, 0.1), ((0.0, 0.0), (math.nan, 0.0)), 8.0)
    with pytest.raises(GaitError, match='shorter'):
        ReplayGait(robot, (0.0, 9.0), ((0.0, 0.0), (0.0, 0.0)), 8.0)
    g = ReplayGait(robot, (0.0, 1.0, 2.0), ((0.0, 0.0), (-1.0, 0.0), (-1.0, 0.5)), 8.0)
    q, rate = g.dof_reference(0.5)
    assert q == pytest.approx((-0.5, 0.0)) and rate == pytest.approx((-1.0, 0.0))
    q, rate = g.dof_reference(5.0)
    assert q == pytest.approx((-1.0, 0.5)) and rate == pytest.approx((0.0, 0.0))
