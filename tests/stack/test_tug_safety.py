"""A tug never outlives its evidence, without ROS.

The behaviour machine runs in closed loop with the simulator's robot model (tests/stack/
plant.py). Mid-tug, capacity_node is killed (no more estimates) or reports each status
without a usable value; the winch must be stopped within 0.1 s of tug time (<= 5 mm of reel at
50 mm/s) and the cycle recorded ``aborted`` with the reason code. The simulator's true ground
is the live RFT solver, so a weaker true sand than the stack's map makes the anchor slip; the
stack must see it from what it measures and stop.
"""
from __future__ import annotations

import math

import pytest
from plant import Plant, fast_config, run_loop, table_ii_machine

from minirquad_sim.ground import LiveGround
from rftgls_ros.behavior import BehaviorMachine, ModeChooser, State, evidence
from rftgls_ros.behavior.slip import SLIP_LEGS, SLIP_PITCH, SLIP_TENSION_DROP, SlipDetector

NAN = float('nan')
MAX_REEL_M = 0.005      # <= 5 mm of reel after the evidence is gone
MAX_STOP_S = 0.1        # within 0.1 s of tug time


# ------------------------------------------------------------------ the evidence rule
@pytest.mark.parametrize('status, capacity, reason, transient', [
    ('unsupported', NAN, 'status_unsupported', False),
    ('degenerate', NAN, 'status_degenerate', False),
    ('out_of_range', NAN, 'status_out_of_range', False),
    ('invalid_input', NAN, 'status_invalid_input', False),
    # the deprecated clamped answer is refused even though it carries a number
    ('extrapolated', 7.45, 'status_extrapolated', False),
    ('stale', NAN, 'status_stale', True),
    ('something_new', 3.0, 'status_something_new', False),
    ('ok', NAN, evidence.NO_VALUE, True),
    ('ok', -1.0, evidence.NO_VALUE, True),
])
def test_judge_refuses_every_status_without_a_usable_value(status, capacity, reason, transient):
    v = evidence.judge(10.0, capacity, status, 9.99, 0.06)
    assert (v.usable, v.reason, v.transient) == (False, reason, transient)


def test_judge_freshness_and_assumed_policy():
    assert evidence.judge(10.0, 3.0, 'ok', 9.95, 0.06).usable
    late = evidence.judge(10.0, 3.0, 'ok', 9.93, 0.06)
    assert (late.usable, late.reason, late.transient) == (False, evidence.TIMEOUT, True)
    never = evidence.judge(10.0, None, 'ok', -math.inf, 0.06)
    assert (never.usable, never.reason) == (False, evidence.NO_ESTIMATE)
    # assumed: refused by default, accepted only for inputs in the accept-list
    v = evidence.judge(10.0, 3.0, 'assumed', 9.99, 0.06, frozenset({'height'}))
    assert (v.usable, v.reason, v.transient) == (False, evidence.ASSUMED_NOT_ACCEPTED, False)
    assert evidence.judge(10.0, 3.0, 'assumed', 9.99, 0.06, frozenset({'height'}),
                          frozenset({'height'})).usable
    v = evidence.judge(10.0, 3.0, 'assumed', 9.99, 0.06, frozenset({'height', 'phi'}),
                       frozenset({'height'}))
    assert v.reason == evidence.ASSUMED_NOT_ACCEPTED and 'phi' in v.detail
    v = evidence.judge(10.0, 3.0, 'assumed', 9.99, 0.06, None, frozenset({'height'}))
    assert (v.usable, v.reason, v.transient) == (False, evidence.ASSUMED_UNKNOWN, True)


def test_judge_needs_the_estimate_at_the_height_sent():
    sent = 0.0428
    assert evidence.judge(10.0, 3.0, 'ok', 9.99, 0.06, height_used=sent, height_sent=sent).usable
    for used in (sent + 2.6e-4, NAN):      # the plan's h before the replay's; none stated
        v = evidence.judge(10.0, 3.0, 'ok', 9.99, 0.06, height_used=used, height_sent=sent)
        assert (v.usable, v.reason, v.transient) == (False, evidence.OTHER_HEIGHT, True), v
    # No height sent (or capacity_node measures it): nothing to compare.
    assert evidence.judge(10.0, 3.0, 'ok', 9.99, 0.06, height_used=NAN).usable
    # An explicit refusal says more than a height not yet caught up with.
    v = evidence.judge(10.0, 3.0, 'assumed', 9.99, 0.06, frozenset({'phi'}),
                       height_used=NAN, height_sent=sent)
    assert v.reason == evidence.ASSUMED_NOT_ACCEPTED


# ------------------------------------------------------------------ faults mid-tug
def _fault_mid_tug(predictor, fault=None, dead=False, t_max=40.0, **cfg_kw):
    """400 g, one cycle; 1 s into the reeling tug the fault starts. Returns what happened."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, evidence_wait_s=1.0, **cfg_kw)
    plant = Plant(0.4, predictor)
    seen = {}

    def inject(p, mach):
        if 'fault_t' not in seen and mach.state == State.TUG \
                and p.robot.winch.spool_velocity > 0.04 and mach.elapsed() > 1.0:
            # The last estimate that was evidence is the one delivered at this time.
            seen['fault_t'], seen['spool0'] = p.t, p.robot.winch.spool_position
            p.capacity_fault = fault
            p.dead = dead
        if 'fault_t' in seen and 'stop_t' not in seen and p.winch_cmd <= 0.0:
            seen['stop_t'] = p.t
        if 'stop_t' in seen and 'reel' not in seen and p.robot.winch.spool_velocity == 0.0:
            seen['reel'] = p.robot.winch.spool_position - seen['spool0']
    run_loop(m, plant, t_max=t_max, on_step=inject)
    return m, plant, seen


FAULTS = {
    'unsupported': lambda p: (NAN, 'unsupported', None),
    'invalid_input': lambda p: (NAN, 'invalid_input', None),
    'degenerate': lambda p: (NAN, 'degenerate', None),
    'out_of_range': lambda p: (NAN, 'out_of_range', None),
    'stale': lambda p: (NAN, 'stale', None),
    'extrapolated': lambda p: (7.45, 'extrapolated', None),
    'assumed': lambda p: (7.45, 'assumed', frozenset({'height'})),
}


@pytest.mark.parametrize('name', sorted(FAULTS) + ['killed'])
def test_winch_stops_and_cycle_aborts_when_evidence_goes(predictor, name):
    if name == 'killed':
        m, plant, seen = _fault_mid_tug(predictor, dead=True)
        reason = evidence.TIMEOUT
    else:
        m, plant, seen = _fault_mid_tug(predictor, FAULTS[name])
        reason = {'assumed': evidence.ASSUMED_NOT_ACCEPTED}.get(name, f'status_{name}')
    assert 'fault_t' in seen, m.reason
    # Stopped within 0.1 s of tug time and at most 5 mm of reel after the last evidence.
    assert seen['stop_t'] - seen['fault_t'] <= MAX_STOP_S, seen
    assert 0.0 <= seen['reel'] <= MAX_REEL_M, seen
    # Recorded: the cycle aborted, with the reason code.
    assert [r.outcome for r in m.records][:1] == ['aborted'], m.records
    assert m.records[0].reason == reason
    assert m.records[0].sled_distance_m < 0.2          # it did not run the tug to the end
    # Retry policy: evidence never came back -> give up with the winch braked.
    assert m.state == State.FINISHED and 'giving up' in m.reason, m.reason
    assert plant.winch_cmd == 0.0
    stops = [e for e in m.events if e['kind'] == 'stop']
    assert stops and stops[0]['reason'] == reason and stops[0]['reel_m'] <= MAX_REEL_M


class _Unreachable:
    """capacity_node's query service as behavior_node sees it once the node is gone: every
    question comes back `stale` with no value (capacity_query.ServicePredictor)."""

    def __init__(self, predictor):
        self.predictor, self.down = predictor, False

    def predict(self, state, phi, pull):
        if not self.down:
            return self.predictor.predict(state, phi, pull)
        from rftgls_core.surfaces.base import CapacityResult
        from rftgls_core.types import Status
        return CapacityResult(phi=phi, status=Status.STALE, method='capacity_query',
                              reason='capacity_query_failed')


def test_check_without_an_answer_is_missing_evidence_not_an_insufficient_anchor(predictor):
    """capacity_node dies while the robot checks its burrowed anchor: the pose check's
    questions go unanswered. That is lost evidence (abort, retry policy, give up), never
    "no mode suffices" (a verdict on the anchor that nobody made)."""
    cfg = fast_config(sled_mass_kg=0.4, cycles=1, evidence_wait_s=1.0)
    service = _Unreachable(predictor)
    m = BehaviorMachine(cfg, ModeChooser(service, cfg.safety_factor, cfg.phis_rad))
    plant = Plant(0.4, predictor)

    def kill_at_check(p, mach):
        if mach.state == State.CHECK and not service.down:
            service.down, p.dead = True, True

    run_loop(m, plant, t_max=40.0, on_step=kill_at_check)
    assert service.down
    assert [r.outcome for r in m.records][:1] == ['aborted'], m.records
    assert m.records[0].reason in (evidence.TIMEOUT, evidence.NO_ESTIMATE), m.records[0]
    assert m.state == State.FINISHED and 'giving up' in m.reason, m.reason
    assert not any('no mode suffices' in e['text'] or 'insufficient' in e['text']
                   for e in m.events), [e['text'] for e in m.events]
    assert plant.winch_cmd == 0.0


def test_choose_waits_for_an_unanswered_query_service_instead_of_refusing(predictor):
    """capacity_node's query service is not up yet when the first walk ends: waiting for an
    answer, not "no mode suffices"; once it answers, the map's choice on the lower bound (DL
    for 400 g: SH's height band reaches an unsupported height, test_behavior_unit.py)."""
    cfg = fast_config(sled_mass_kg=0.4, cycles=1, evidence_wait_s=5.0)
    service = _Unreachable(predictor)
    service.down = True
    m = BehaviorMachine(cfg, ModeChooser(service, cfg.safety_factor, cfg.phis_rad))
    plant = Plant(0.4, predictor)
    seen = {}

    def answer_later(p, mach):
        if mach.state == State.CHOOSE:
            seen.setdefault('t', p.t)
            if p.t - seen['t'] > 2.0:
                service.down = False
    run_loop(m, plant, t_max=60.0, on_step=answer_later)
    texts = [e['text'] for e in m.events]
    assert any('query is unanswered' in t for t in texts), texts
    assert m.decisions and m.decisions[0].mode == 'DL', texts
    assert m.records[0].outcome == 'ok', m.records
    # Never answered: refused once evidence_wait_s has passed, winch braked.
    service2 = _Unreachable(predictor)
    service2.down = True
    m2 = BehaviorMachine(cfg, ModeChooser(service2, cfg.safety_factor, cfg.phis_rad))
    plant2 = Plant(0.4, predictor)
    run_loop(m2, plant2, t_max=30.0)
    assert m2.state == State.REFUSED and plant2.winch_cmd == 0.0, m2.reason
    assert m2.records[0].outcome == 'refused'


def test_fallback_never_overrides_an_explicit_no_value(predictor):
    m, _plant, seen = _fault_mid_tug(predictor, FAULTS['unsupported'],
                                     own_capacity_fallback=True)
    assert seen['reel'] <= MAX_REEL_M
    assert m.records[0].outcome == 'aborted'
    assert not any('own map' in e['text'] for e in m.events)


def test_fallback_off_by_default_and_only_when_silent_if_configured(predictor):
    assert fast_config().own_capacity_fallback is False
    # Explicitly configured: a silent capacity_node is replaced by the own map at Table II h.
    m, _plant, seen = _fault_mid_tug(predictor, dead=True, own_capacity_fallback=True)
    assert m.records[0].outcome == 'ok', m.records
    assert any('own_capacity_fallback' in e['text'] for e in m.events)


def test_aborted_tug_is_retried_when_evidence_returns(predictor):
    # unsupported for 1 s, then capacity_node answers again: abort, wait, re-check, tug on.
    def flaky(p):
        if p.t - flaky.t0 < 1.0:
            return (NAN, 'unsupported', None)
        return None
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)

    def inject(p, mach):
        if p.capacity_fault is None and mach.state == State.TUG and mach.elapsed() > 1.0:
            flaky.t0 = p.t
            p.capacity_fault = flaky
    run_loop(m, plant, on_step=inject)
    assert [r.outcome for r in m.records] == ['aborted', 'ok'], m.records
    assert [r.cycle for r in m.records] == [1, 2]
    assert m.records[0].reason == 'status_unsupported'
    assert m.state == State.FINISHED
    assert any(e.get('to') == 'WAIT_EVIDENCE' for e in m.events)


def test_no_tug_starts_without_evidence(predictor):
    # capacity_node never gives a value: CHECK waits capacity_wait, records the abort, and the
    # winch never reels in.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, evidence_wait_s=0.5)
    plant = Plant(0.4, predictor)
    plant.capacity_fault = lambda p: (NAN, 'unsupported', None)
    run_loop(m, plant, t_max=30)
    assert m.records[0].outcome == 'aborted' and m.records[0].reason == 'status_unsupported'
    assert not any(e.get('to') == 'TUG' for e in m.events)
    assert plant.robot.winch.spool_position <= 0.0     # only paid out while walking


def test_no_tug_starts_on_an_estimate_at_another_height(predictor):
    # capacity_node answers for a height 0.3 mm off the one behavior_node sends (a replay's
    # correction it never took up): its numbers answer another question. CHECK waits, then
    # records the abort.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, evidence_wait_s=0.5)
    plant = Plant(0.4, predictor)
    plant.estimate_height = lambda p: p.h + 3e-4
    run_loop(m, plant, t_max=30)
    assert m.records[0].outcome == 'aborted', m.records
    assert m.records[0].reason == evidence.OTHER_HEIGHT
    assert not any(e.get('to') == 'TUG' for e in m.events)
    assert plant.robot.winch.spool_position <= 0.0     # only paid out while walking


def test_a_tug_starts_only_once_the_estimate_caught_up_with_the_height(predictor):
    # The demo's race: as CHECK begins, behavior_node corrects its height (a planned burrow's
    # replay) and capacity_node needs a cold lower bound at the new one. Here its estimates
    # stay 0.3 mm off for CHECK's first 0.3 s. The tug starts on an estimate at the height
    # sent, and never reels on one at another.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    plant.estimate_height = lambda p: p.h + 3e-4 if (
        m.state == State.CHECK and m.elapsed() < 0.3) else p.h
    reeled_at_other_h, entered = [], []

    def watch(p, mach):
        if mach.state == State.TUG and not entered:
            entered.append(mach.obs.capacity_h == mach.height)
        if p.winch_cmd > 0.0 and not mach.burrow.taking_up \
                and mach.obs.capacity_h != mach.height:
            reeled_at_other_h.append((p.t, mach.obs.capacity_h, mach.height))
    run_loop(m, plant, t_max=60, on_step=watch)
    assert [r.outcome for r in m.records] == ['ok'], m.records
    assert entered == [True]
    assert not reeled_at_other_h, reeled_at_other_h[:3]
    check = next(e['t'] for e in m.events if e.get('to') == 'CHECK')
    tug = next(e['t'] for e in m.events if e.get('to') == 'TUG')
    assert tug - check >= 0.3


# ------------------------------------------------------------------ slip detector rules
def test_slip_detector_rules():
    d = SlipDetector()
    assert d.update(0.1, 0.0, 0.05, (-0.7, 0.5)) is None          # slack: no reference yet
    assert d.update(1.0, 0.01, 0.05, (-0.7, 0.5)) is None
    assert d.update(1.9, 0.02, 0.05 + math.radians(0.8), (-0.7, 0.5)) is None
    assert d.update(1.9, 0.03, 0.05 + math.radians(2.0), (-0.7, 0.5)).reason == SLIP_PITCH
    d.reset()
    d.update(1.9, 0.0, 0.0, (-0.7, 0.5))
    assert d.update(1.9, 0.001, 0.0, (-0.7 + math.radians(3), 0.5)).reason == SLIP_LEGS
    d.reset()
    d.update(2.0, 0.0, 0.0, None)
    assert d.update(1.6, 0.002, 0.0, None) is None                 # not reeled enough yet
    ev = d.update(1.6, 0.004, 0.0, None)
    assert ev.reason == SLIP_TENSION_DROP and ev.peak_tension == 2.0
    d.reset()                                                       # a sliding sled: steady
    for k in range(200):
        assert d.update(1.96, 0.001 * k, 0.0, (-0.7, 0.5)) is None


# ------------------------------------------------------------------ weaker true sand
def _weak_sand(predictor, sled, scale):
    """One cycle with the simulator's true medium scaled by ``scale``; slip (m) at detection."""
    m = table_ii_machine(predictor, sled_mass_kg=sled, cycles=1)
    plant = Plant(sled, predictor, ground=LiveGround(medium_scale=scale))
    seen = {}

    def watch(p, mach):
        if 'slip_at_detect' not in seen and any(
                str(e.get('reason', '')).startswith('slip_') for e in mach.events):
            seen['slip_at_detect'] = p.tug_slip
            seen['mode'] = mach.mode
    run_loop(m, plant, t_max=90, on_step=watch)
    return m, plant, seen


def test_weaker_sand_400g_dl_chosen_on_the_lower_bound_holds(predictor):
    # Live direct solver, M90 x 0.7. The paper's point-estimate rule would burrow SH for 400 g,
    # which holds only 1.1-1.7 N < 1.96 N in this sand and slips. On the lower bound the robot
    # burrows DL (SH's height band reaches an unsupported height), which in this sand still
    # holds about 3.5 N: no slip, no false alarm, the sled comes in.
    m, plant, seen = _weak_sand(predictor, 0.4, 0.7)
    assert 'slip_at_detect' not in seen, [e['text'] for e in m.events][-20:]
    rec = m.records[0]
    assert (rec.mode, rec.outcome) == ('DL', 'ok'), rec
    assert plant.tug_slip < 1e-3 and rec.reel_lower_margin_n >= 0.0


def test_1kg_is_refused_before_any_tug(predictor):
    # The map's point estimate says DH holds 5.2-5.7 N >= 4.9 N; its lower bound over 34 +-
    # 2 mm is 4.73 N < 4.9 N. No tug at all (REFUSED, winch braked, never reeled in), with the
    # shortfall in the reason. (On the point estimate it tugged, and in 30 % weaker sand DH
    # slipped on and on.)
    m, plant, seen = _weak_sand(predictor, 1.0, 0.7)
    rec = m.records[0]
    assert (m.state, rec.mode, rec.outcome, rec.reason) == (
        State.REFUSED, '-', 'refused', 'no_sufficient_mode'), rec
    assert 'strongest DH has a lower bound of 4.73 N' in m.reason, m.reason
    assert rec.lower_n == pytest.approx(4.73, abs=0.01) and rec.point_n > rec.need_n
    assert not any(e.get('to') == 'TUG' for e in m.events)
    assert plant.robot.winch.spool_position <= 0.0 and plant.winch_cmd == 0.0


def test_weaker_sand_800g_dh_slips_is_detected_and_stopped(predictor):
    # 800 g needs 3.92 N: DH's lower bound (4.73 N) covers it on the map. In sand 50 % weaker
    # DH holds less; the slip is seen within 20 mm, and nothing is stronger than DH: stop,
    # winch braked.
    m, plant, seen = _weak_sand(predictor, 0.8, 0.5)
    assert seen.get('mode') == 'DH', [e['text'] for e in m.events][-20:]
    assert 0.0 < seen['slip_at_detect'] <= 0.020
    rec = m.records[0]
    assert (rec.mode, rec.outcome) == ('DH', 'stopped') and rec.reason.startswith('slip_'), rec
    assert m.state == State.FINISHED and 'after a slip' in m.reason
    assert plant.tug_slip <= 0.025 and plant.winch_cmd == 0.0


def test_weaker_sand_600g_dl_slips_is_detected_and_reburrows_dh(predictor):
    # 30 % weaker sand leaves DL at 3.5 N > 2.94 N (see the next test); at 50 % it holds
    # 2.74 N, so the 600 g tug in the chosen mode (DL) slips (and digs itself in after ~5 mm).
    m, plant, seen = _weak_sand(predictor, 0.6, 0.5)
    assert seen.get('mode') == 'DL'
    assert 0.0 < seen['slip_at_detect'] <= 0.020
    rec = m.records[0]
    assert rec.mode == 'DL+DH', rec
    assert rec.outcome == 'ok' and m.state == State.FINISHED, m.reason


def test_30_percent_weaker_sand_600g_dl_holds_without_false_alarm(predictor):
    m, plant, seen = _weak_sand(predictor, 0.6, 0.7)
    assert 'slip_at_detect' not in seen
    assert plant.tug_slip < 1e-3
    assert m.records[0].mode == 'DL' and m.records[0].outcome == 'ok'


# ------------------------------------------------------------------ every cycle leaves a row
def _link_lost_mid_tug(predictor, **cfg_kw):
    """400 g; 1 s into the reeling tug the robot link goes for good (the bridge killed: the
    host hears nothing more). Returns the machine and the plant."""
    import dataclasses
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, **cfg_kw)
    plant = Plant(0.4, predictor)
    advance = plant.advance
    seen: dict = {}

    def lost_advance(dt):
        obs = advance(dt)
        if 'lost' not in seen and m.state == State.TUG and m.elapsed() > 1.0:
            seen['lost'] = obs
        if 'lost' in seen:
            return dataclasses.replace(seen['lost'], t=plant.t, link_ok=False)
        return obs
    plant.advance = lost_advance
    return m, plant, seen


def test_a_link_that_never_returns_leaves_the_cycle_row_with_its_reason(predictor):
    m, plant, seen = _link_lost_mid_tug(predictor, link_wait_s=3.0)
    run_loop(m, plant, t_max=40.0)
    assert 'lost' in seen and m.state == State.FINISHED, m.reason
    assert 'link did not come back' in m.reason and plant.winch_cmd == 0.0
    rec = m.records[-1]
    assert (rec.cycle, rec.outcome, rec.reason) == (1, 'aborted', 'link_stale'), rec


def test_stopping_the_node_mid_wait_leaves_the_cycle_row(predictor):
    m, plant, seen = _link_lost_mid_tug(predictor)
    run_loop(m, plant, t_max=15.0)              # stopped while still waiting (link_wait_s 60)
    assert m.state == State.WAIT_LINK and not m.records
    m.close(m.open_reason())                    # what behavior_node does on SIGINT
    assert [(r.outcome, r.reason) for r in m.records] == [('aborted', 'link_stale')]
    assert m.winch == 0.0
    m.close('shutdown')                         # once only
    assert len(m.records) == 1


def test_an_untrusted_link_stops_the_tug_and_the_row_says_why(predictor):
    """The bridge counts >= 10 % of the MCU's frames lost (LinkState UNTRUSTED) for 1.5 s
    mid-tug: the samples still arrive fresh, but the winch stops in the step that hears it,
    and the cycle's row (resumed and finished after the link is trusted again) keeps the
    reason."""
    import dataclasses
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    advance = plant.advance
    seen: dict = {}

    def lossy_advance(dt):
        obs = advance(dt)
        if 'from' not in seen and m.state == State.TUG and plant.winch_cmd > 0.04 \
                and m.elapsed() > 0.5:
            seen['from'], seen['spool0'] = plant.t, plant.robot.winch.spool_position
        if 'from' in seen and plant.t < seen['from'] + 1.5:
            return dataclasses.replace(obs, link_ok=False, link_fault='link_untrusted',
                                       link_detail='40 % of frames lost over 1.0 s')
        return obs

    def watch(p, mach):
        if 'from' in seen and 'stop_t' not in seen and p.winch_cmd == 0.0:
            seen['stop_t'] = p.t
        if 'stand_t' not in seen and 'stop_t' in seen and p.robot.winch.spool_velocity == 0.0:
            seen['stand_t'] = p.t
            seen['reel'] = p.robot.winch.spool_position - seen['spool0']

    plant.advance = lossy_advance
    run_loop(m, plant, t_max=60.0, on_step=watch)
    assert 'from' in seen and m.state == State.FINISHED, m.reason
    assert seen['stop_t'] - seen['from'] <= 0.02 + 1e-9         # the next 10 ms control step
    assert seen['stand_t'] - seen['from'] <= MAX_STOP_S
    assert 0.0 <= seen['reel'] <= MAX_REEL_M, seen
    stops = [e for e in m.events if e['kind'] == 'stop']
    assert stops and stops[0]['reason'] == 'link_untrusted', stops
    assert any('40 % of frames lost' in e['text'] for e in m.events)
    rec = m.records[0]
    assert (rec.cycle, rec.outcome, rec.reason) == (1, 'ok', 'link_untrusted'), rec
