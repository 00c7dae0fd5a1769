"""The walk-burrow-tug action's pieces without DDS: the machine's cancel in closed loop with the
simulator's robot model (tests/stack/plant.py), and how a run becomes the action's result and
feedback (rftgls_ros.tug_action)."""
from __future__ import annotations

import math

import pytest
from plant import Plant, fast_config, run_loop

from rftgls_interfaces.msg import CycleOutcome
from rftgls_ros.behavior import BehaviorMachine, ModeChooser, State
from rftgls_ros.behavior.tug_series import TugSample
from rftgls_ros.tug_action import OUTCOMES, cycle_outcome, feedback, run_succeeded


def machine(predictor, **kw) -> BehaviorMachine:
    cfg = fast_config(sled_mass_kg=0.4, **kw)
    return BehaviorMachine(cfg, ModeChooser(predictor, cfg.safety_factor, cfg.phis_rad))


def cancel_in(state: State, after_s: float):
    """on_step hook: cancel once the machine has been `after_s` in `state`; keeps what the
    cancel's step commanded."""
    seen: dict = {}

    def hook(plant, m):
        if 'cmd' not in seen and m.state == state and m.elapsed() >= after_s:
            seen['spool_v'] = plant.robot.winch.spool_velocity
            m.cancel('test')
            seen['cmd'] = m.step(plant.advance(0.002))
            plant.apply(seen['cmd'])
    return hook, seen


def test_cancel_mid_tug_brakes_the_winch_keeps_the_anchor_and_records_the_cycle(predictor):
    m = machine(predictor, cycles=2)
    plant = Plant(0.4, predictor)
    hook, seen = cancel_in(State.TUG, 0.5)
    run_loop(m, plant, on_step=hook)
    assert seen['spool_v'] > 0.02                        # it was reeling in
    cmd = seen['cmd']
    assert cmd.winch == 0.0 and cmd.oneshots == []       # braked; the legs stay burrowed
    assert m.state == State.FINISHED and m.done
    assert [(r.cycle, r.outcome, r.reason) for r in m.records] == [(1, 'cancelled',
                                                                    'cancelled')]
    assert m.records[0].tug_s > 0.4                      # the tug's time up to the cancel
    assert plant.robot.winch.command == 0.0
    assert not run_succeeded(m)
    n = len(m.records)
    m.cancel('again')                                    # over: nothing changes
    assert len(m.records) == n


def test_cancel_while_walking_stands_and_after_a_cycle_keeps_its_record(predictor):
    m = machine(predictor, cycles=2)
    plant = Plant(0.4, predictor)
    # Cycle 1 ran its course; cycle 2 is walking (its first WALK is cycle 1's).
    hook, seen = cancel_in(State.WALK, 0.3)
    run_loop(m, plant, on_step=lambda p, mach: hook(p, mach) if mach.records else None)
    assert seen['cmd'].oneshots == [('gait', 'stand')] and seen['cmd'].winch == 0.0
    assert [(r.cycle, r.outcome) for r in m.records] == [(1, 'ok'), (2, 'cancelled')]
    assert m.records[1].walk_s >= 0.3 and m.records[1].walk_j > 0   # the walk so far counts


def test_result_maps_every_outcome_and_success_needs_every_cycle_ok(predictor):
    m = machine(predictor, cycles=1)
    run_loop(m, Plant(0.4, predictor))
    assert run_succeeded(m)
    (rec,) = m.records
    out = cycle_outcome(rec)
    assert (out.cycle, out.outcome, out.mode, out.reason) == (1, CycleOutcome.OK, 'DL', '')
    assert out.energy_j == pytest.approx(rec.walk_j + rec.burrow_j + rec.tug_j)
    assert out.sled_distance_m == rec.sled_distance_m > 0.1
    # Every outcome word of the cycle report has its own constant; an unknown one is 0.
    assert sorted(OUTCOMES.values()) == [CycleOutcome.OK, CycleOutcome.REFUSED,
                                         CycleOutcome.STOPPED, CycleOutcome.ABORTED,
                                         CycleOutcome.CANCELLED] == [1, 2, 3, 4, 5]
    rec.outcome = 'stopped'
    assert cycle_outcome(rec).outcome == CycleOutcome.STOPPED and not run_succeeded(m)
    rec.outcome = 'something new'
    assert cycle_outcome(rec).outcome == 0


def test_feedback_margin_is_capacity_minus_tension(predictor):
    m = machine(predictor, cycles=1)
    fb = feedback(m, None)
    assert (fb.state, fb.cycle, fb.capacity_status) == ('WAIT_INPUTS', 0, '')
    assert all(math.isnan(x) for x in (fb.tension_n, fb.capacity_n, fb.capacity_lower_n,
                                       fb.margin_n))
    fb = feedback(m, TugSample(1.0, 2.5, 4.0, 3.0, 'ok', 'TUG'))
    assert (fb.tension_n, fb.capacity_n, fb.capacity_lower_n, fb.margin_n,
            fb.capacity_status) == (2.5, 4.0, 3.0, 1.5, 'ok')
    fb = feedback(m, TugSample(1.0, 2.5, math.nan, math.nan, 'stale', 'TUG'))
    assert math.isnan(fb.margin_n) and fb.capacity_status == 'stale'
