"""A re-burrow steps off the sand the last burrow dug (STEP_OFF, behavior/walk.py): the state
machine driven in closed loop by the simulator's robot model (tests/stack/plant.py), a heavier
sled mid-tug forcing the margin guard's stop and a re-burrow into DH, as in
test_behavior_unit.py's test_machine_heavier_mid_tug_stops_then_reburrows."""
from __future__ import annotations

import math

import pytest
from plant import Plant, run_loop, table_ii_machine  # tests/stack/plant.py

from rftgls_ros.behavior import BehaviorConfig, State


def reburrow_run(predictor, on_step=None, **kw):
    """One 400 g cycle whose sled becomes 0.8 kg after 50 mm of reel-in: DL's guard stop, the
    re-burrow into DH. Returns the machine, the plant and per step (state, commands, x of p,
    slack of the rope: its free length minus the distance from p to the sled, m)."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, **kw)
    plant = Plant(0.4, predictor, heavier_at=0.05, heavier_mass=0.8)
    steps = []
    apply = plant.apply

    def recording(cmd):
        r = plant.robot
        slack = r.winch.free_length() - r.winch.geometry(r.x_p, r.h)[0]
        steps.append((m.state, cmd, r.x_p, slack))
        apply(cmd)
    plant.apply = recording
    run_loop(m, plant, on_step=on_step, t_max=150.0)
    return m, plant, steps


def states_in_order(steps) -> list[State]:
    out: list[State] = []
    for state, *_ in steps:
        if not out or out[-1] != state:
            out.append(state)
    return out


def test_a_reburrow_walks_step_off_m_before_it_burrows(predictor):
    m, plant, steps = reburrow_run(predictor)
    order = states_in_order(steps)
    assert m.state == State.FINISHED and m.records[0].mode == 'DL+DH', (m.reason, order)
    assert m.records[0].outcome == 'ok'
    k = order.index(State.STEP_OFF)
    assert order[k - 2:k + 2] == [State.HOLD, State.SLACKEN, State.STEP_OFF, State.BURROW]
    off = [(cmd, x, slack) for state, cmd, x, slack in steps if state == State.STEP_OFF]
    # walking (the walk gait renewed every step, as in WALK), the tether paid out as fast as
    # the robot is estimated to walk, not with the walk's margin
    assert off[0][0].oneshots == [('gait', 'walk')]
    assert all(cmd.walking and cmd.winch == -m.cfg.walk_speed_m_s for cmd, _, _ in off)
    # so the slack stays the slacken's (the scripted walk moves at walk_speed_m_s): the
    # re-burrow's take-up need not reel in the 60 mm a walk's margin would have added
    assert off[-1][2] == pytest.approx(off[0][2], abs=3e-3), (off[0][2], off[-1][2])
    assert 'still slack' not in ' '.join(e['text'] for e in m.events)
    # for step_off_m at walk_speed_m_s: the scripted walk moves p at 0.03 m/s, as the config
    # estimates, so p moved 0.18 m (to one 10 ms machine step: 0.3 mm)
    walked = off[-1][1] - off[0][1]
    assert walked == pytest.approx(m.cfg.step_off_m, abs=2e-3)
    # the step off ends on a stand (a command, not the walk's renewal running out)
    first = next(i for i, s in enumerate(steps) if s[0] == State.STEP_OFF)
    after = next(cmd for state, cmd, *_ in steps[first:] if state == State.BURROW)
    assert ('gait', 'stand') in after.oneshots
    assert not after.walking
    # the height sent while stepping off is the walking height, not the dug anchor's
    assert all(cmd.height == m.cfg.h_walk_m for cmd, _, _ in off)
    # the cycle's walk includes the step off: 1.5 s walk + 6 s step off
    assert m.records[0].walk_s == pytest.approx(
        m.cfg.walk_time_s + m.cfg.step_off_m / m.cfg.walk_speed_m_s, abs=0.05)
    assert any('step 180 mm off the dug sand first' in e['text'] for e in m.events)


def test_a_step_off_of_zero_reburrows_in_place(predictor):
    m, plant, steps = reburrow_run(predictor, step_off_m=0.0)
    order = states_in_order(steps)
    assert State.STEP_OFF not in order
    k = order.index(State.SLACKEN)
    assert order[k:k + 2] == [State.SLACKEN, State.BURROW]
    assert m.records[0].mode == 'DL+DH' and m.records[0].outcome == 'ok'
    assert m.records[0].walk_s == pytest.approx(m.cfg.walk_time_s, abs=0.05)


def test_a_link_loss_during_the_step_off_stands_and_then_walks_what_is_left(predictor):
    seen: dict = {}

    def cut(p, mach):
        if mach.state == State.STEP_OFF and 'cut' not in seen and mach.elapsed() > 2.0:
            seen['cut'], seen['x'] = p.t, p.robot.x_p
            p.link_ok = False
        if 'cut' in seen and not p.link_ok and p.t - seen['cut'] > 1.5:
            seen['moved'] = p.robot.x_p - seen['x']
            p.link_ok = True
    m, plant, steps = reburrow_run(predictor, on_step=cut)
    texts = ' '.join(e['text'] for e in m.events)
    assert 'during STEP_OFF' in texts and 'walking on' in texts, texts
    # stood through the outage, the payout stopped with it
    assert abs(seen['moved']) < 2e-3, seen
    order = states_in_order(steps)
    assert [s for s in order if s in (State.STEP_OFF, State.WAIT_LINK)][:3] == [
        State.STEP_OFF, State.WAIT_LINK, State.STEP_OFF]
    # the two parts of the step off together walk step_off_m, then the re-burrow into DH
    walked = sum(b[2] - a[2] for a, b in zip(steps, steps[1:]) if a[0] == State.STEP_OFF)
    assert walked == pytest.approx(m.cfg.step_off_m, abs=4e-3)
    assert m.records[0].mode == 'DL+DH' and m.records[0].outcome == 'ok', m.reason


def test_a_cancel_during_the_step_off_stands_the_robot_and_books_the_walk(predictor):
    seen: dict = {}

    def cancel(p, mach):
        if mach.state == State.STEP_OFF and mach.elapsed() > 1.0 and 'walk_s' not in seen:
            seen['walk_s'] = mach.cycle.walk_s
            mach.cancel('operator')
    m, plant, steps = reburrow_run(predictor, on_step=cancel)
    last = m.step(plant.advance(0.002))
    assert m.state == State.FINISHED and m.records[0].outcome == 'cancelled'
    stands = [cmd for _, cmd, *_ in steps if ('gait', 'stand') in cmd.oneshots]
    assert stands and last.winch == 0.0 and not last.walking
    assert m.records[0].walk_s == pytest.approx(seen['walk_s'] + 1.0, abs=0.05)


@pytest.mark.parametrize('bad', [-0.1, math.nan, math.inf])
def test_a_step_off_that_is_not_a_distance_is_refused(bad):
    with pytest.raises(ValueError, match='step_off_m'):
        BehaviorConfig(step_off_m=bad).check()
    with pytest.raises(ValueError, match='walk_speed_m_s'):
        BehaviorConfig(walk_speed_m_s=0.0).check()


def outage_run(predictor, when, plant_cls=Plant, seconds: float = 1.0):
    """One 400 g Table II cycle with the link cut for `seconds` once `when(plant, machine)`;
    the states in order and the machine."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = plant_cls(0.4, predictor)
    seen: dict = {}
    order: list[State] = []

    def cut(p, mach):
        if not order or order[-1] != mach.state:
            order.append(mach.state)
        if 'cut' not in seen and when(p, mach):
            seen['cut'] = p.t
            p.link_ok = False
        if 'cut' in seen and not p.link_ok and p.t - seen['cut'] > seconds:
            p.link_ok = True
    run_loop(m, plant, on_step=cut)
    assert 'cut' in seen
    return m, order


def after_outage(order: list[State]) -> list[State]:
    k = order.index(State.WAIT_LINK)
    return order[k:k + 4]


def test_legs_that_left_the_anchor_during_an_outage_are_burrowed_again_off_the_dug_sand(
        predictor):
    """The robot stood up during the outage (an MCU reset): the anchor is gone and the tether
    taut from the tug; the mode is burrowed again as any re-burrow (slacken, step off)."""
    def stand_mid_tug(p, mach):
        if mach.state == State.TUG and mach.elapsed() > 1.0:
            g = p.gaits['stand']
            p.robot.set_gait(g.kind, g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
            return True
        return False
    m, order = outage_run(predictor, stand_mid_tug)
    assert after_outage(order) == [State.WAIT_LINK, State.SLACKEN, State.STEP_OFF,
                                   State.BURROW], order
    assert any('left the DL pose during the outage' in e['text'] for e in m.events)
    assert m.records[0].mode == 'DL+DL' and m.records[0].outcome == 'ok', m.records


def test_a_burrow_cut_by_an_outage_starts_over_off_the_sand_its_legs_dug(predictor):
    # DL's sequence under way on the MCU: its legs have dug
    def mid_burrow(p, mach):
        return mach.state == State.BURROW and mach.burrow.commanded and mach.elapsed() > 1.5
    m, order = outage_run(predictor, mid_burrow)
    assert after_outage(order) == [State.WAIT_LINK, State.SLACKEN, State.STEP_OFF,
                                   State.BURROW], order
    assert m.records[0].mode == 'DL' and m.records[0].outcome == 'ok', m.records


def test_a_burrow_cut_before_its_legs_moved_starts_over_in_place(predictor):
    # still taking up the slack, no burrow command sent: nothing dug, no step off
    def taking_up(p, mach):
        return mach.state == State.BURROW and mach.burrow.taking_up
    m, order = outage_run(predictor, taking_up, seconds=0.8)
    assert after_outage(order)[:2] == [State.WAIT_LINK, State.BURROW], order
    assert State.STEP_OFF not in order
    assert m.records[0].mode == 'DL' and m.records[0].outcome == 'ok', m.records
