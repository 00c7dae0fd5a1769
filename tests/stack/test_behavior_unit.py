"""Plain (no ROS) tests of the behaviour: required force, energy model, mode chooser, tether,
and the state machine driven in closed loop by the simulator's robot model (SimRobot, the
same physics minirquad_sim runs, stepped in-process; tests/stack/plant.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Status
from rftgls_ros.behavior import (
    ANCHOR_MODES,
    BehaviorConfig,
    BehaviorMachine,
    EnergyModel,
    ForceNeed,
    ModeChooser,
    Observation,
    State,
    write_report,
)
from rftgls_ros.behavior.model import versus
from rftgls_ros.behavior.report import read_csv
from rftgls_ros.tether import TetherTracker

G = 9.81


def test_force_need_nominal_and_update():
    need = ForceNeed(0.4, 0.5)
    assert need.value == pytest.approx(0.5 * 0.4 * G)
    assert need.update([1.0, 2.0]) is None           # too few samples
    assert need.update([2.2] * 10) == pytest.approx(2.2)
    assert need.value == pytest.approx(2.2)
    need.update([1.8] * 10)
    assert need.value == pytest.approx(2.0)          # blended, alpha 0.5
    need.raise_floor(2.5)
    assert need.value == 2.5


def test_energy_model_prior_ratios_then_measured_scale():
    e = EnergyModel(prior_sh=1.0)
    assert [e.estimate(m) for m in ('DH', 'DL', 'SH')] == pytest.approx([1.32, 1.26, 1.0])
    e.update('SH', 4.0)
    assert e.estimate('SH') == 4.0
    assert e.estimate('DH') == pytest.approx(1.32 * 4.0)
    e.update('DH', 4.0)                              # measured DH as cheap as SH
    assert e.estimate('DH') == 4.0
    e.update('SH', float('nan'))                     # ignored
    assert e.estimate('SH') == 4.0


def band_lower(predictor, mode: str, phi: float) -> float:
    """Reference lower bound of a mode, computed here from the map itself: the smallest
    capacity at five heights across its Table II mean +- two standard deviations (a height
    without a value counts 0: the anchor may hold nothing there)."""
    m = ANCHOR_MODES[mode]
    s = m.expected_state()
    caps = []
    for h in np.linspace(m.h - 2 * m.h_sd, m.h + 2 * m.h_sd, 5):
        r = predictor.predict(AnchorState(float(h), s.theta_b, s.theta_l1, s.theta_l2), phi,
                              'backward')
        caps.append(r.capacity_N if r.status == Status.OK else 0.0)
    return min(caps)


PHIS = (0.0, math.radians(-20.0))


def test_chooser_400g_is_dl_because_sh_band_reaches_an_unsupported_height(predictor):
    # 400 g needs 0.5 x 0.4 x g = 1.96 N. SH's point estimate at its Table II pose (47 mm)
    # is 1.99 N at -20 deg: the paper's point-estimate rule picks SH. But h is not measured,
    # only known to lie in 47 +- 4 mm, and at 51 mm SH holds nothing (unsupported): its lower
    # bound is 0 N. DL (36 +- 4 mm) keeps 3.59 N at 40 mm, and is cheaper than DH.
    need = 0.5 * 0.4 * G
    d = ModeChooser(predictor, 1.0).choose(need, EnergyModel())
    assert d.mode == 'DL', d.table()
    sh, dl, dh = (d.candidate(n) for n in ('SH', 'DL', 'DH'))
    assert sh.point >= need and not sh.sufficient        # the point estimate would tug on SH
    assert sh.weakest == 0.0 and 'no value somewhere in its height band' in sh.why
    assert dl.weakest == pytest.approx(min(band_lower(predictor, 'DL', p) for p in PHIS))
    assert dl.weakest < dl.point and dh.sufficient
    assert 'cheapest' in d.reason and 'lower bound' in d.reason


def test_chooser_600g_picks_dl_in_our_model(predictor):
    # 600 g needs 2.94 N: DL's lower bound (3.59 N at 40 mm) covers it and DL is cheaper than
    # DH (the paper: DH; our RFT-GLS map rates DL higher than the paper's Fig. 10(b)).
    d = ModeChooser(predictor, 1.0).choose(0.5 * 0.6 * G, EnergyModel())
    assert d.mode == 'DL', d.table()
    assert not d.candidate('SH').sufficient


def test_chooser_safety_factor_on_the_lower_bound(predictor):
    # SF 1.9 x 1.96 N = 3.73 N: above DL's lower bound (3.59 N) though below its point
    # estimate (4.37 N), so only DH (lower bound 4.73 N) suffices.
    d = ModeChooser(predictor, 1.9).choose(0.5 * 0.4 * G, EnergyModel())
    dl = d.candidate('DL')
    assert dl.point >= 1.9 * 0.5 * 0.4 * G > dl.weakest
    assert d.mode == 'DH', d.table()


def test_a_lower_bound_within_the_guards_share_of_the_need_does_not_suffice(predictor):
    # The margin guard stops the winch at stop_ratio (0.97) x the lower bound and the sled
    # moves only at its sliding tension, the need. A sled whose need lies between 0.97 x DL's
    # lower bound and the bound itself: DL would pass a check on "lower bound >= need" and
    # then every tug on it would stop at the guard before the sled moved. The machine's
    # chooser takes DH, and the cycle tugs the sled home on its first burrow.
    dl = min(band_lower(predictor, 'DL', p) for p in PHIS)
    mass = 0.985 * dl / (0.5 * G)                 # need = 0.985 x DL's lower bound
    m = table_ii_machine(predictor, sled_mass_kg=mass, cycles=1)
    d = m.chooser.choose(m.need.value, m.energy)
    assert d.mode == 'DH' and d.candidate('DL').weakest >= m.need.value, d.table()
    assert d.required_n == pytest.approx(m.need.value / m.cfg.stop_ratio), d.table()
    run_loop(m, Plant(mass, predictor))
    texts = ' '.join(e['text'] for e in m.events)
    assert [(r.mode, r.outcome) for r in m.records] == [('DH', 'ok')], texts
    assert 'margin guard' not in texts, texts


def test_chooser_refuses_1kg_although_dh_point_estimate_covers_it(predictor):
    # 1 kg needs 4.90 N. DH's point estimate (5.24 N at 34 mm) covers it, its lower bound over
    # 34 +- 2 mm (4.73 N at 36 mm) does not: no tug, and the reason names the shortfall.
    need = 0.5 * 1.0 * G
    d = ModeChooser(predictor, 1.0).choose(need, EnergyModel())
    dh = d.candidate('DH')
    assert d.mode is None, d.table()
    assert dh.point >= need > dh.weakest
    assert dh.weakest == pytest.approx(min(band_lower(predictor, 'DH', p) for p in PHIS))
    assert d.reason == (f'no mode suffices: need {need:.2f} N x 1.00 / 1.00, strongest DH has a '
                        f'lower bound of {dh.weakest:.2f} N')


def test_chooser_refuses_with_reason(predictor):
    d = ModeChooser(predictor, 1.0).choose(0.5 * 1.5 * G, EnergyModel())
    assert d.mode is None
    assert 'no mode suffices' in d.reason and 'DH' in d.reason


def test_chooser_invalid_prediction_is_not_sufficient():
    class Bad:
        def predict(self, state, phi, pull):
            return CapacityResult(phi, Status.UNSUPPORTED, 'test', reason='unsupported')
    d = ModeChooser(Bad()).choose(1.0, EnergyModel())
    assert d.mode is None and 'unsupported' in d.table()


def test_chooser_stronger_than(predictor):
    d = ModeChooser(predictor).choose(0.5 * 0.4 * G, EnergyModel(), exclude=['SH'],
                                      stronger_than=2.0)
    assert d.mode == 'DL'


def test_a_bound_just_short_of_the_need_never_prints_equal_to_it():
    # Seen in make demo: 'holds 2.02 N (lower bound) < 2.02 N required'.
    assert versus(2.018, 2.022) == '2.018 N < 2.022 N'
    assert versus(1.99999, 2.0) == '1.99999 N < 2.00000 N'
    assert versus(2.0149, 2.0151) == '2.01 N < 2.02 N'       # apart at two decimals already
    assert versus(2.02, 2.02) == '2.02 N >= 2.02 N'          # equal is enough
    assert versus(3.06, 2.06) == '3.06 N >= 2.06 N'


def test_tether_length_and_phi():
    t = TetherTracker(rope_length=0.5, attach_height=0.01)
    t.update(0.0)
    t.update(0.15)
    t.update(0.3)
    assert t.free_length == pytest.approx(0.2)
    t.update(5.0)                                     # reset jump ignored
    assert t.free_length == pytest.approx(0.2)
    assert math.degrees(t.phi(0.01 + 0.2 * math.sin(math.radians(20)))) == pytest.approx(-20)


# ------------------------------------------------------------------ closed loop, no ROS
from plant import Plant, fast_config, run_loop, table_ii_machine  # noqa: E402  (tests/stack/plant.py)


def test_machine_400g_chooses_dl_on_the_lower_bound_and_completes_cycles(predictor):
    # DL, not the paper's SH: SH's height band reaches an unsupported height (chooser tests).
    m = table_ii_machine(predictor, sled_mass_kg=0.4)
    plant = Plant(0.4, predictor)
    run_loop(m, plant)
    assert m.state == State.FINISHED, m.reason
    assert [r.mode for r in m.records] == ['DL', 'DL']
    for r in m.records:      # the decision basis is in the row, and no reel ran below the need
        assert r.point_n > r.lower_n >= m.cfg.safety_factor * 0.5 * 0.4 * G
        assert r.reel_lower_margin_n >= 0.0 and 'DL: cheapest' in r.decision
    assert all(r.outcome == 'ok' for r in m.records)
    assert plant.tug_slip < 1e-3
    assert all(r.burrow_j > 0 and r.walk_j > 0 and r.tug_j > 0 for r in m.records)
    kinds = {e['kind'] for e in m.events}
    assert {'transition', 'decision', 'live', 'cycle'} <= kinds


def test_the_report_keeps_the_bound_each_tug_was_started_on(predictor):
    """lower_n is the choice's bound (a prediction at the mode's pose); check_lower_n the one
    CHECK started the tug on: capacity_node's lower bound at the pose the burrow reached,
    times the learned scale, as the machine saw it at the step CHECK handed over to TUG."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=2)
    started: list[float] = []
    prev = [m.state]

    def watch(plant, machine):
        if prev[0] == State.CHECK and machine.state == State.TUG:
            started.append(machine.obs.capacity_lower * machine.chooser.scale)
        prev[0] = machine.state

    run_loop(m, Plant(0.4, predictor), on_step=watch)
    assert m.state == State.FINISHED and len(started) == len(m.records) == 2, m.records
    for r, bound in zip(m.records, started):
        assert r.check_lower_n == bound >= r.need_n, (r, bound)
    refused = table_ii_machine(predictor, sled_mass_kg=1.5, cycles=1)
    run_loop(refused, Plant(1.5, predictor), t_max=20)
    assert math.isnan(refused.records[0].check_lower_n)     # no tug, no bound it started on


def test_step_returns_its_events_once(predictor):
    """The node publishes what step returns: every event exactly once, in order."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    returned = []
    obs = Observation(t=0.0)
    while plant.t < 60.0 and not m.done:
        cmd = m.step(obs)
        returned += cmd.events
        plant.apply(cmd)
        for _ in range(5):
            obs = plant.advance(0.002)
    assert m.done and returned and returned == list(m.events)


def test_the_burrowed_height_is_sent_as_table_ii_with_its_band(predictor):
    """MiniRQuad does not measure h: after a burrow the machine sends the mode's Table II mean
    with a band of two of its standard deviations (DL: 36 +- 2 mm SD -> +- 4 mm), and says so."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    obs, sent = Observation(t=0.0), {}
    while plant.t < 60.0 and not m.done and 'TUG' not in sent:
        cmd = m.step(obs)
        sent.setdefault(str(m.state), cmd)
        plant.apply(cmd)
        for _ in range(5):
            obs = plant.advance(0.002)
    walk, tug = sent['WALK'], sent['TUG']
    assert (walk.height, walk.height_source) == (m.cfg.h_walk_m, 'h_walk_m parameter (walking), '
                                                 'not measured')
    assert math.isnan(walk.height_band)
    assert (tug.height, tug.height_band) == (pytest.approx(0.036), pytest.approx(0.004))
    assert tug.height_source == 'Table II mean of DL (paper), not measured'


@pytest.mark.parametrize('bad', [dict(cycles=0), dict(slow_ratio=0.99, stop_ratio=0.9),
                                 dict(tug_speed_m_s=0.0), dict(phis_rad=(2.0,))])
def test_behavior_config_check_refuses(bad):
    with pytest.raises(ValueError):
        BehaviorConfig(**bad).check()
    assert BehaviorConfig().check() == BehaviorConfig()


def test_machine_600g_never_sh(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.6, cycles=1)
    plant = Plant(0.6, predictor)
    run_loop(m, plant)
    assert m.state == State.FINISHED, m.reason
    assert m.records[0].mode == 'DL' and m.records[0].outcome == 'ok'
    assert plant.tug_slip < 1e-3


def test_machine_refuses_too_heavy_sled(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=1.5, cycles=1)
    run_loop(m, Plant(1.5, predictor), t_max=20)
    assert m.state == State.REFUSED
    assert 'no mode suffices' in m.reason
    assert m.records[0].outcome == 'refused'


def test_machine_heavier_mid_tug_stops_then_reburrows(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    # 400 g burrows DL; at 0.8 kg (3.92 N) the tension reaches the margin guard on DL's lower
    # bound (about 3.6 N), and only DH's lower bound (4.73 N) is stronger.
    plant = Plant(0.4, predictor, heavier_at=0.05, heavier_mass=0.8)
    run_loop(m, plant)
    texts = [e['text'] for e in m.events]
    assert any('margin guard' in t for t in texts), texts
    assert plant.tug_slip < 2e-3
    assert m.records[0].mode == 'DL+DH', m.records
    assert m.state == State.FINISHED and m.records[0].outcome == 'ok'


def test_machine_heavier_without_stronger_mode_holds(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor, heavier_at=0.05, heavier_mass=2.0)
    run_loop(m, plant)
    assert plant.tug_slip < 2e-3
    assert m.state == State.FINISHED and m.records[0].outcome == 'stopped', m.reason
    assert 'stopped before slip' in m.reason


def test_machine_link_loss_mid_tug_waits_then_resumes(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    seen = {}

    def cut(p, mach):
        if mach.state == State.TUG and 'cut' not in seen and mach.elapsed() > 1.0:
            seen['cut'] = p.t
            p.link_ok = False
        if 'cut' in seen and p.link_ok is False:
            assert mach.winch == 0.0 or mach.state == State.TUG
            if p.t - seen['cut'] > 1.0:
                seen['state_during'] = mach.state
                p.link_ok = True
    run_loop(m, plant, on_step=cut)
    assert seen['state_during'] == State.WAIT_LINK
    assert m.state == State.FINISHED and m.records[0].outcome == 'ok'
    texts = ' '.join(e['text'] for e in m.events)
    assert 'link stale during TUG' in texts and 're-checking' in texts


def test_a_link_loss_mid_walk_stands_the_robot_with_its_payout(predictor):
    # The host loses its inputs mid-walk while the MCU still hears it (a stalled host process,
    # not an unplugged cable): the MCU walks its gait on its own, so with the payout stopped a
    # walk that went on would take up the slack and drag against the tether.
    m = table_ii_machine(predictor, sled_mass_kg=0.6, cycles=1)
    plant = Plant(0.6, predictor)
    seen = {}

    def cut(p, mach):
        if mach.state == State.WALK and 'cut' not in seen and mach.elapsed() > 0.5:
            seen['cut'], seen['x'] = p.t, p.robot.x_p
            p.link_ok = False
        if 'cut' in seen and not p.link_ok:
            seen['pulled'] = max(seen.get('pulled', 0.0), p.robot.winch.tension)
        if 'cut' in seen and not p.link_ok and p.t - seen['cut'] > 1.5:
            seen['moved'] = p.robot.x_p - seen['x']
            p.link_ok = True
        if mach.state == State.CHOOSE and 'chose' not in seen:
            seen['chose'] = p.robot.x_p
    run_loop(m, plant, on_step=cut, t_max=30.0)
    texts = ' '.join(e['text'] for e in m.events)
    assert 'link stale during WALK' in texts and 'walking on' in texts, texts
    # It stood through the 1.5 s outage (the gait covers 45 mm at 0.03 m/s) and never pulled
    # on the tether (walking on, it took up the slack and dragged at its 1.16 N friction).
    assert abs(seen['moved']) < 2e-3 and seen['pulled'] < 0.1, seen
    assert seen['chose'] > 0.0, seen


def test_a_walk_is_renewed_every_step_and_ends_on_a_stand(predictor):
    # The node renews a walk while Commands.walking (GaitCommand.valid_until, 0.25 s) and the
    # bridge stands a walk left unrenewed; the end of a walk is a command, not that timeout.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    steps = []
    apply = plant.apply

    def recording(cmd):
        steps.append((m.state, cmd.oneshots, cmd.walking))
        apply(cmd)
    plant.apply = recording
    run_loop(m, plant, t_max=4.0)
    walking = [i for i, (state, _, w) in enumerate(steps) if w]
    assert walking and all(steps[i][0] == State.WALK for i in walking)
    end = walking[-1] + 1                       # the step that left WALK
    assert steps[end][0] != State.WALK and ('gait', 'stand') in steps[end][1], steps[end]
    assert not any(w for _, _, w in steps[end:])


def test_a_recheck_at_an_unchanged_pose_asks_no_question(predictor):
    # The re-check after a link gap keeps the anchor's sufficient check while the measured pose
    # stays within the slip thresholds of it: no capacity question (each one blocks the
    # node's step for a service round trip), the live evidence still gates the tug.
    class Counting:
        def __init__(self, inner):
            self.inner, self.calls = inner, 0

        def predict(self, state, phi, pull=''):
            self.calls += 1
            return self.inner.predict(state, phi, pull)

    counting = Counting(predictor)
    cfg = fast_config(sled_mass_kg=0.4, cycles=1)
    m = BehaviorMachine(cfg, ModeChooser(counting, cfg.safety_factor, cfg.phis_rad))
    plant = Plant(0.4, predictor)
    seen = {}

    def cut(p, mach):
        if mach.state == State.TUG and 'cut' not in seen and mach.elapsed() > 1.0:
            seen['cut'], seen['calls'] = p.t, counting.calls
            p.link_ok = False
        if 'cut' in seen and not p.link_ok and p.t - seen['cut'] > 1.0:
            p.link_ok = True
        if 'cut' in seen and 'resumed' not in seen and p.link_ok and mach.state == State.TUG:
            seen['resumed'] = counting.calls
    run_loop(m, plant, on_step=cut)
    assert m.records[0].outcome == 'ok', m.records
    assert seen['calls'] > 0 and seen['resumed'] == seen['calls'], seen
    assert 'pose unchanged since that check' in ' '.join(e['text'] for e in m.events)


def test_machine_legs_moved_during_link_loss_reburrows(predictor):
    # During the outage the robot stands up (as after an MCU reset): the checked anchor is
    # gone, so the machine burrows again instead of re-checking at the assumed height.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    seen = {}

    def cut(p, mach):
        if mach.state == State.TUG and 'cut' not in seen and mach.elapsed() > 1.0:
            seen['cut'] = p.t
            p.link_ok = False
            g = p.gaits['stand']
            p.robot.set_gait(g.kind, g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
        if 'cut' in seen and not p.link_ok and p.t - seen['cut'] > 1.0:
            p.link_ok = True
    run_loop(m, plant, on_step=cut)
    texts = ' '.join(e['text'] for e in m.events)
    assert 'left the DL pose during the outage' in texts, texts
    assert m.records[0].mode == 'DL+DL' and m.records[0].outcome == 'ok', m.records


class _LosesBurrows(Plant):
    """The plant drops the first ``lost`` burrow commands (a command lost on its way, or a
    burrow undone at once): the legs stay where they were."""

    def __init__(self, *a, lost: int, **kw):
        super().__init__(*a, **kw)
        self.lost = lost

    def apply(self, cmd) -> None:
        kept = []
        for topic, value in cmd.oneshots:
            if topic == 'burrow' and self.lost > 0:
                self.lost -= 1
                continue
            kept.append((topic, value))
        cmd.oneshots = kept
        super().apply(cmd)


def test_a_table_ii_burrow_that_missed_its_pose_is_burrowed_again(predictor):
    # The burrow times out with the legs still standing. Table II's height is the height of
    # the mode's final pose: checked with it at the standing legs, the anchor would be judged
    # (and tugged on) as a burrow that never happened.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = _LosesBurrows(0.4, predictor, lost=1)
    run_loop(m, plant)
    texts = [e['text'] for e in m.events]
    missed = [t for t in texts if 'from its final pose' in t]
    assert len(missed) == 1 and 'the anchor here is unknown' in missed[0], '\n'.join(texts)
    checks = [t for t in texts if t.startswith('check DL at the measured pose')]
    assert len(checks) == 1 and 'thetaL1 -40.0' in checks[0], checks   # only the real burrow
    assert m.state == State.FINISHED and m.records[0].mode == 'DL+DL', m.records
    assert m.records[0].outcome == 'ok'
    # The missed burrow taught the energy model nothing; the real one did.
    learnt = [t for t in texts if t.startswith('burrow DL: ')]
    assert 'not counted' in learnt[0] and 'energy estimates now' in learnt[1], learnt


def test_burrows_that_never_reach_their_pose_stop_the_cycle_untugged(predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, burrow_timeout_s=2.0)
    plant = _LosesBurrows(0.4, predictor, lost=99)       # (2 s: the legs never move)
    reeled = []
    run_loop(m, plant, on_step=lambda p, mach: reeled.append(
        mach.state == State.TUG and mach.winch > 0.0))
    assert not any(reeled)
    assert m.records[0].outcome == 'stopped', m.records
    assert 'DL did not reach its final pose' in m.reason and 'giving up' in m.reason, m.reason
    assert m.records[0].mode == '+'.join(['DL'] * m.cfg.max_burrows_per_cycle)


def test_a_reel_in_carries_when_its_estimate_ages_out(predictor):
    # Every tug reel-in is sent with its evidence deadline, the estimate's sample time plus
    # estimate_timeout_s, for the MCU to brake at whatever the host does then; nothing else
    # the winch does (take-up, pay-out, stops) carries one.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    obs, sent = Observation(t=0.0), []
    while plant.t < 60.0 and not m.done:
        cmd = m.step(obs)
        sent.append((m.state, cmd.winch, cmd.winch_valid_until, obs.t_capacity))
        plant.apply(cmd)
        for _ in range(5):
            obs = plant.advance(0.002)
    assert m.records[0].outcome == 'ok', m.records
    reels = [(v, tc) for s, w, v, tc in sent if s == State.TUG and w > 0.0]
    assert len(reels) > 100
    assert all(v == tc + m.cfg.estimate_timeout_s for v, tc in reels)
    assert all(v == 0.0 for s, w, v, _ in sent if not (s == State.TUG and w > 0.0))
    assert any(w > 0.0 for s, w, _, _ in sent if s != State.TUG)     # the take-up reels too


def test_after_the_last_cycle_the_robot_stays_anchored_under_the_sled(predictor):
    """The arrived sled still pulls its sliding tension on the braked winch: legs swung out of
    the sand under it (a stand) would let it drag the robot."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    plant = Plant(0.4, predictor)
    run_loop(m, plant)
    assert m.state == State.FINISHED and m.records[0].outcome == 'ok', m.records
    r = plant.robot
    legs, x_p, slip = r.leg_angles(), r.x_p, plant.slip
    assert r.winch.tension > 0.9 * 0.5 * 0.4 * 9.81       # the sled's load is on the rope
    for _ in range(500):                                  # 1 s more of the finished run
        plant.apply(m.step(plant.advance(0.002)))
    assert r.winch.command == 0.0 and r.leg_angles() == legs
    assert r.x_p == x_p and plant.slip == slip


def test_report_csv_and_png(tmp_path, predictor):
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    run_loop(m, Plant(0.4, predictor))
    csv_path, png_path = write_report(m.records, tmp_path)
    rows = read_csv(csv_path)
    assert rows[0].mode == 'DL' and rows[0].cycle == 1
    got, want = rows[0], m.records[0]     # the decision basis survives the CSV (4 decimals)
    assert (got.lower_n, got.point_n, got.energy_pred_j, got.check_lower_n) == pytest.approx(
        (want.lower_n, want.point_n, want.energy_pred_j, want.check_lower_n), abs=1e-4)
    assert got.decision == want.decision and got.decision.startswith('DL: cheapest')
    assert png_path.stat().st_size > 10_000


def test_a_report_cut_short_while_plotting_keeps_both_tables(tmp_path, predictor, monkeypatch):
    """behavior_node's report at its stop: the cycle table and the tug series are on disk
    before any plot is drawn, so a stop the watchdog (or launch's SIGKILL) cuts while
    matplotlib starts loses at most the plots. The cut is a plot that never returns."""
    import types

    from rftgls_ros import behavior_node
    from rftgls_ros.behavior import report
    from rftgls_ros.behavior.tug_series import TugSeries
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1)
    run_loop(m, Plant(0.4, predictor))
    series = TugSeries()
    for k in range(5):
        series.add(0.1 * k, 1.0, 3.0, 2.5, 'ok', 'TUG')

    class Cut(BaseException):
        pass

    def cut(*_a, **_k):
        raise Cut
    monkeypatch.setattr(report, 'plot_report', cut)
    monkeypatch.setattr(report, 'plot_tug_series', cut)
    node = types.SimpleNamespace(report_dir=str(tmp_path), machine=m, tug_series=series,
                                 report_stem='r', cfg=m.cfg, get_logger=None)
    with pytest.raises(Cut):
        behavior_node.BehaviorNode.write_report(node)
    assert read_csv(tmp_path / 'r.csv')[0].mode == m.records[0].mode
    assert len((tmp_path / 'r_tug.csv').read_text().splitlines()) == 1 + 5


def test_modes_match_table_ii():
    assert ANCHOR_MODES['DH'].expected_state().h == 0.034
    assert math.degrees(ANCHOR_MODES['SH'].retract[1]) == pytest.approx(-20)


def test_burrow_modes_are_table_ii_or_planned():
    assert BehaviorConfig(burrow_modes='table_ii').check().burrow_modes == 'table_ii'
    assert BehaviorConfig(burrow_modes='planned').check().burrow_modes == 'planned'
    with pytest.raises(ValueError, match='burrow_modes must be one of table_ii, planned'):
        BehaviorConfig(burrow_modes='paper').check()


@pytest.mark.parametrize('status, lower, usable, reason', [
    ('ok', 2.0, True, 'ok'),
    ('ok', float('nan'), False, 'lower_bound_missing'),     # never on the point estimate
    ('ok', None, False, 'lower_bound_missing'),
    ('assumed', 2.0, False, 'assumed_not_accepted'),
])
def test_evidence_needs_a_lower_bound(status, lower, usable, reason):
    from rftgls_ros.behavior import evidence
    v = evidence.judge(1.0, 2.5, status, 1.0, 0.05, frozenset({'height'}), frozenset(),
                       lower)
    assert (v.usable, v.reason) == (usable, reason), v


def test_a_tug_that_crawls_in_the_slow_band_until_its_timeout_reburrows_stronger(predictor):
    """capacity_node's bound for DL drops, once the tug runs, to just above the need: the
    sled's sliding tension (1.96 N) sits at 96 % of 2.04 N, inside the slow band, and the reel
    crawls (6 mm/s). At the tug timeout the robot re-burrows into a stronger mode (DH), whose
    tug runs at speed; a run without a stronger mode, or a timeout at full speed, stops the
    cycle as before. (A bound that low before the tug is refused at CHECK: the test below.)"""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, tug_timeout_s=25.0)
    plant = Plant(0.4, predictor)
    plant.capacity_fault = lambda p: (2.04, 'ok', None) \
        if m.mode == 'DL' and m.state == State.TUG else None
    reels = []
    run_loop(m, plant, on_step=lambda p, mach: reels.append((mach.mode, mach.winch))
             if mach.state == State.TUG else None)
    texts = ' '.join(e['text'] for e in m.events)
    assert 'tug timeout (25 s) with the tension at 96 % of the capacity' in texts, texts
    assert m.records[0].mode == 'DL+DH' and m.records[0].outcome == 'ok', m.records
    dl = [w for mode, w in reels if mode == 'DL' and w > 0.0]
    dh = [w for mode, w in reels if mode == 'DH' and w > 0.0]
    assert max(dl[len(dl) // 2:]) < 0.2 * m.cfg.tug_speed_m_s      # crawling
    assert max(dh) == m.cfg.tug_speed_m_s                          # at speed
    # no stronger mode than DH: the cycle stops at the timeout, winch braked
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, tug_timeout_s=25.0)
    plant = Plant(0.4, predictor)
    plant.capacity_fault = lambda p: (2.04, 'ok', None) if m.state == State.TUG else None
    run_loop(m, plant)
    assert m.records[0].outcome == 'stopped' and m.records[0].reason == 'tug_slow', m.records
    assert m.records[0].mode == 'DL+DH'
    # a timeout at full speed is no thin margin: stopped, no re-burrow
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, tug_timeout_s=2.0)
    run_loop(m, Plant(0.4, predictor))
    assert m.records[0].mode == 'DL' and m.records[0].outcome == 'stopped', m.records
    assert 'tug timeout (2 s)' in m.reason


def test_the_tug_ratio_is_the_guards_when_the_crawl_reels_in_time_else_the_speed_that_does():
    from rftgls_ros.behavior.reel import reel_fraction, tug_ratio
    cfg = BehaviorConfig(tug_timeout_s=40.0)   # 50 mm/s: 2 m in 40 s, 0.2 m at the 10 % crawl
    assert tug_ratio(cfg, 0.0) == tug_ratio(cfg, 0.2) == cfg.stop_ratio
    assert tug_ratio(cfg, 2.0) == pytest.approx(cfg.slow_ratio, abs=1e-12)   # full speed only
    assert tug_ratio(cfg, 5.0) == pytest.approx(cfg.slow_ratio, abs=1e-12)   # not even that
    for reel_m in (0.3, 0.42, 1.0, 1.9):
        r = tug_ratio(cfg, reel_m)
        assert cfg.slow_ratio < r < cfg.stop_ratio
        # at that ratio the reel's law runs exactly fast enough
        assert reel_fraction(cfg, r) * cfg.tug_speed_m_s * cfg.tug_timeout_s \
            == pytest.approx(reel_m, rel=1e-9)


def test_a_bound_that_would_leave_the_reel_crawling_past_its_timeout_is_refused_at_check(
        predictor):
    """The same thin bound for DL (2.04 N: the sliding tension 1.96 N at 96 %, where the reel
    crawls at 6 mm/s) known before the tug. With more tether left than the crawl brings in
    within the tug timeout, CHECK refuses it (reel.tug_ratio) and the robot re-burrows DH at
    once, instead of crawling 25 s first; with a tether the crawl brings in in time, DL tugs.
    The ratio is worked out here from the reel's law as BehaviorConfig states it: reeling
    reel_m in t_out needs the speed fraction f = reel_m / (v t_out); the reel runs at f where
    the tension / capacity ratio is stop - f (stop - slow), and at min_speed_fraction or more
    up to the guard."""
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, tug_timeout_s=25.0)
    plant = Plant(0.4, predictor)
    plant.capacity_fault = lambda p: (2.04, 'ok', None) if m.mode == 'DL' else None
    reels, checked = [], []

    def watch(p, mach):
        if mach.state == State.TUG:
            reels.append((mach.mode, mach.winch))
        if mach.state == State.CHECK and mach.mode == 'DL':
            checked.append(mach.tether.free_length)

    run_loop(m, plant, on_step=watch)
    texts = ' '.join(e['text'] for e in m.events)
    cfg = m.cfg
    f = (checked[-1] - cfg.arrive_length_m) / (cfg.tug_speed_m_s * cfg.tug_timeout_s)
    assert cfg.min_speed_fraction < f < 1.0, f     # the crawl would take longer than 25 s
    ratio = cfg.stop_ratio - f * (cfg.stop_ratio - cfg.slow_ratio)
    required = 0.5 * 0.4 * G / ratio
    assert 2.04 < required < 0.5 * 0.4 * G / cfg.slow_ratio, required
    assert f'capacity_node: DL holds 2.04 N < {required:.2f} N required (lower bound)' in texts, \
        texts
    assert not [w for mode, w in reels if mode == 'DL' and w > 0.0], reels   # never reeled
    # the re-burrow's decision (~/events) carries the bound it asked for and the ratio
    last = [e for e in m.events if e['kind'] == 'decision' and 'required_n' in e][-1]
    assert last['mode'] == 'DH' and last['tug_ratio'] == pytest.approx(ratio, abs=1e-9)
    assert last['required_n'] == pytest.approx(required, abs=1e-9), last
    assert 'tug timeout' not in texts, texts
    assert (m.records[0].mode, m.records[0].outcome) == ('DL+DH', 'ok'), m.records
    # A tether short enough for the crawl: the same bound tugs DL, slowly, and brings it in.
    m = table_ii_machine(predictor, sled_mass_kg=0.4, cycles=1, tug_timeout_s=25.0,
                         rope_length_m=0.15)
    plant = Plant(0.4, predictor)
    plant.capacity_fault = lambda p: (2.04, 'ok', None) if m.mode == 'DL' else None
    reels.clear()
    run_loop(m, plant, on_step=lambda p, mach: reels.append((mach.mode, mach.winch))
             if mach.state == State.TUG else None)
    texts = ' '.join(e['text'] for e in m.events)
    assert (m.records[0].mode, m.records[0].outcome) == ('DL', 'ok'), texts
    dl = [w for mode, w in reels if mode == 'DL' and w > 0.0]
    assert dl and max(dl[len(dl) // 2:]) < 0.2 * cfg.tug_speed_m_s, dl      # it crawled
