"""Planned burrows without ROS: the gait chooser on the shipped gait maps (planned.py), the leg
ramp (gait_motion.py), the simulator's gait poses (minirquad_sim/gait_pose.py) and the machine
running a planned gait in closed loop with the simulator's robot model (plant.py).

References: the chosen gait is checked against the planner itself (`plan_from_map`, the code
`rftgls plan burrow` runs) on the same map; the probability of holding against the normal
CDF written out here with math.erf.
"""
from __future__ import annotations

import math

import pytest
from plant import Plant, fast_config, run_loop

from minirquad_sim.gait_pose import GaitPoses
from rftgls_core.planning.planner import plan_from_map
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Provenance, Status
from rftgls_ros.behavior import BehaviorConfig, BehaviorMachine, EnergyModel, State
from rftgls_ros.behavior.gait_motion import gait_duration, gait_targets
from rftgls_ros.behavior.planned import (
    GaitChooser,
    PlanUnavailable,
    gait_name,
    p_hold,
    sled_map,
)
from rftgls_ros.capacity.node_predictor import DEFAULT_MAP, node_predictor
from rftgls_ros.capacity.range_bound import scan_points

PHIS = (0.0, math.radians(-20.0))
G = 9.81


@pytest.fixture(scope='module')
def predictor():
    # As capacity_node runs it (ros2_ws/params/capacity_node.yaml): the map, answered live
    # next to its support edge.
    return node_predictor(DEFAULT_MAP, robot=None, medium=None, edge_live_method='direct-warm')


def check_lower(predictor, answer, phis=PHIS) -> float:
    """The lower bound CHECK computes for a gait burrowed at its predicted pose: the smallest
    capacity of the predictor over h +- 2 sigma (the band scan's points) at every tether
    angle, 0 where the predictor has no value (written out here, not the chooser's code)."""
    h, tb = answer.pose[0], answer.pose[1]
    lows = []
    for phi in phis:
        for hh in scan_points(h, 2 * answer.pose_sigma[0], 0.0, math.inf):
            r = predictor.predict(AnchorState(hh, tb, *answer.gait.final), phi, 'backward')
            ok = r.status == Status.OK and r.capacity_N is not None
            lows.append(r.capacity_N if ok and math.isfinite(r.capacity_N) else 0.0)
    return min(lows)


@pytest.mark.parametrize('sled', [0.4, 0.6])
def test_chooses_the_cheapest_gait_the_planner_and_the_check_both_cover(predictor, sled):
    gmap = sled_map('minirquad', sled)
    ch = GaitChooser(predictor, gmap, 1.0, PHIS, 0.95)
    need = 0.5 * sled * G
    d = ch.choose(need, ch.energy_model(EnergyModel()))
    plan = plan_from_map(gmap, PHIS, need, 0.95)
    # Reference: the planner's candidates by energy, the first whose planner lower bound and
    # CHECK's lower bound at its predicted pose both cover the need.
    covering = sorted((a for a in plan.answers if a.candidate and a.lower_bound_N >= need),
                      key=lambda a: a.energy_elec_J)
    want = next(a for a in covering if check_lower(predictor, a) >= need)
    assert d.mode is not None
    g = ch.gaits[d.mode]
    assert g.answer.gait.same_motion(want.gait), d.reason
    # A cheaper covering gait the check would find short is shown with why it was passed.
    for a in covering[:covering.index(want)]:
        c = d.candidate(gait_name(a))
        assert c is not None and not c.sufficient and 'capacity_node at the predicted pose' \
            in c.why, (c, d.reason)
    # The burrow as the machine sees it: the predicted pose and a 2-sigma band of its h.
    mode = ch.modes[d.mode]
    assert mode.h == pytest.approx(want.pose[0]) and mode.final == g.final
    assert mode.h_band == pytest.approx(2 * want.pose_sigma[0])
    assert 0.5 < g.p_hold <= 1.0


class MapEndsAt:
    """A predictor with no value above h_max (m), as a map whose grid ends there answers."""

    def __init__(self, inner, h_max: float):
        self.inner, self.h_max, self.asked = inner, h_max, 0

    def predict(self, state, phi, pull):
        self.asked += 1
        if state.h > self.h_max:
            return CapacityResult(phi, Status.OUT_OF_RANGE, 'test', reason='out_of_grid')
        return self.inner.predict(state, phi, pull)


def test_a_gait_whose_band_leaves_the_checks_map_is_not_chosen(predictor):
    """The planner's cheapest gait for 400 g, its height band cut by a map ending inside it:
    CHECK would find no value there and re-burrow, so the choice passes it over and says why;
    asked again, the chooser counts on what it found without asking again."""
    gmap = sled_map('minirquad', 0.4)
    plan = plan_from_map(gmap, PHIS, 1.96, 0.95)
    first = plan.chosen
    cut = MapEndsAt(predictor, first.pose[0] + 0.5 * first.pose_sigma[0])
    ch = GaitChooser(cut, gmap, 1.0, PHIS, 0.95)
    energy = ch.energy_model(EnergyModel())
    d = ch.choose(1.96, energy)
    assert d.mode not in (None, gait_name(first)), d.reason
    c = d.candidate(gait_name(first))
    assert not c.sufficient and c.weakest == 0.0 and 'out_of_range at h' in c.why, c
    asked = cut.asked
    assert ch.choose(1.96, energy).mode == d.mode and cut.asked == asked


@pytest.mark.parametrize('sled', [0.4, 0.6])
def test_an_unanswered_confirmation_waits_for_evidence(predictor, sled):
    """capacity_node's query service silent at CHOOSE: no gait, and the decision is the one
    unanswered gait with every status `stale` (CHOOSE waits on that, burrow.py), however many
    gaits the planner found short; nothing is kept against the gait and nothing more asked.
    (On the 600 g map the planner's cheapest gait is short of the need, 3.00 N < 3.03 N: shown
    beside the unanswered ones, its `ok` statuses made CHOOSE refuse the sled, seen once in
    `test_planned_on_weaker_sand_replans_or_stops_within_20_mm` under load.)"""
    class Silent:
        asked = 0

        def predict(self, state, phi, pull):
            Silent.asked += 1
            return CapacityResult(phi, Status.STALE, 'capacity_query', reason='no answer')
    ch = GaitChooser(Silent(), sled_map('minirquad', sled), 1.0, PHIS, 0.95)
    d = ch.choose(0.5 * sled * G, ch.energy_model(EnergyModel()))
    assert d.mode is None and len(d.candidates) == 1, d.reason
    (c,) = d.candidates
    assert c.weakest is None and not c.sufficient and set(c.statuses) == {'stale'}, c
    assert not ch.observed and not ch.confirmed
    assert Silent.asked == len(PHIS)      # the band scan stops at its first unanswered question


def test_p_hold_is_the_normal_tail_at_the_weakest_angle(predictor):
    ch = GaitChooser(predictor, sled_map('minirquad', 0.6), 1.0, PHIS, 0.95)
    d = ch.choose(2.94, ch.energy_model(EnergyModel()))
    a = ch.gaits[d.mode].answer
    want = min(0.5 * (1 - math.erf((2.94 - c) / (s * math.sqrt(2)))) for c, s, _ in a.per_phi)
    assert p_hold(a, 2.94) == pytest.approx(want, abs=1e-9)
    assert p_hold(a, 2.94, scale=0.7) < p_hold(a, 2.94)


def test_after_a_slip_it_replans_stronger_or_refuses(predictor):
    ch = GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0, PHIS, 0.95)
    energy = ch.energy_model(EnergyModel())
    first = ch.choose(1.96, energy)
    weakest = first.candidate(first.mode).weakest
    ch.scale = 0.7                          # the anchor slipped at 70 % of the prediction
    again = ch.choose(1.96, energy, exclude=[first.mode], stronger_than=weakest * 0.7)
    assert again.mode not in (None, first.mode)
    assert ch.gaits[again.mode].answer.lower_bound_N * 0.7 >= 1.96
    ch.scale = 0.2                          # nothing in the gait space holds that
    assert ch.choose(1.96, energy).mode is None


def test_no_gait_map_for_the_sled_is_refused_in_one_line(predictor):
    with pytest.raises(PlanUnavailable) as e:
        sled_map('minirquad', 0.5)
    assert str(e.value).startswith("burrow_modes 'planned': no gait map for a 500 g sled")
    assert '\n' not in str(e.value) and '400 g, 600 g' in str(e.value)
    with pytest.raises(PlanUnavailable, match='tether angles'):
        GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0, (math.radians(-35.0),))


def test_config_accepts_planned_and_checks_its_confidence():
    assert BehaviorConfig(burrow_modes='planned').check().burrow_modes == 'planned'
    with pytest.raises(ValueError, match='plan_confidence'):
        BehaviorConfig(burrow_modes='planned', plan_confidence=1.0).check()


def test_leg_ramp_runs_at_the_gait_speed_through_stand_and_retract_to_final():
    start, retract, final, speed = (-0.9, -1.1), (-1.0, -0.4), (-0.4, 0.5), 1.0
    dt = 0.01
    t_end = gait_duration(start, retract, final, speed)
    ts = [i * dt for i in range(int(t_end / dt) + 50)]
    xs = [gait_targets(t, start, retract, final, speed) for t in ts]
    steps = [max(abs(b[0] - a[0]), abs(b[1] - a[1])) for a, b in zip(xs, xs[1:])]
    assert max(steps) <= speed * dt + 1e-12            # never faster than the gait
    stood = [i for i, x in enumerate(xs) if x == pytest.approx((0.0, 0.0))]
    assert stood and ts[stood[0]] == pytest.approx(1.1, abs=dt)   # stands first (1.1 rad)
    assert min(x[0] for x in xs[stood[0]:]) == pytest.approx(-1.0)  # then the retract
    assert xs[-1] == pytest.approx(final)
    assert ts[next(i for i, x in enumerate(xs) if x == pytest.approx(final))] == \
        pytest.approx(t_end, abs=dt)
    with pytest.raises(ValueError):
        gait_targets(0.0, start, retract, final, 0.0)


def test_sim_gait_poses_match_map_gaits_only():
    poses = GaitPoses.for_sled(0.4)
    assert poses is not None and GaitPoses.for_sled(0.5) is None
    r = math.radians
    h, tb = poses.pose((r(-40), r(-20)), (r(-40), r(-20)))
    assert 0.03 < h < 0.06 and tb > 0.0
    assert poses.pose((r(-40), r(-20)), (r(-30), r(-20))) is None


@pytest.mark.slow
def test_planned_gait_closed_loop_modelled_height_and_holds(predictor):
    plant = Plant(0.4, predictor, gait_poses=GaitPoses.for_sled(0.4))
    # The shipped walk (2.5 s): it leaves the legs further back than the gait's retract.
    cfg = fast_config(burrow_modes='planned', cycles=1, walk_time_s=2.5).check()
    m = BehaviorMachine(cfg, GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0,
                                         cfg.phis_rad, cfg.plan_confidence))
    seen = {}

    def watch(plant, machine):
        if machine.state == State.TUG:
            seen['height'] = machine.height_input()
            seen['pitch'] = plant.robot.theta_b
    run_loop(m, plant, t_max=60, on_step=watch)
    r = m.records[0]
    assert r.outcome == 'ok', [e['text'] for e in m.events][-10:]
    gait = m.chooser.gaits[r.mode]
    h, band, _, prov = seen['height']
    assert prov is Provenance.MODELLED and h == pytest.approx(gait.answer.pose[0])
    assert band == pytest.approx(2 * gait.answer.pose_sigma[0])
    # The simulated body settled where the gait map predicts (gait_pose.py).
    assert seen['pitch'] == pytest.approx(gait.answer.pose[1], abs=1e-3)
    assert r.p_hold == pytest.approx(gait.p_hold) and r.reel_lower_margin_n >= 0.0
    assert plant.tug_slip < 0.002


def test_a_measured_burrow_updates_its_gait_and_its_neighbours_more_than_far_gaits(predictor):
    ch = GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0, PHIS, 0.95)
    e = ch.energy_model(EnergyModel())
    r = math.radians
    names = {tuple(round(math.degrees(x)) for x in v): k for k, v in e.gaits.items()}
    here = names[(-40, -20, -40, -20)]
    near = names[(-40, -20, -20, -20)]           # one grid step (20 deg) away
    far = names[(-60, -40, -20, 30)] if (-60, -40, -20, 30) in names else None
    before = {k: e.estimate(k) for k in e.ratios}
    assert before[here] == pytest.approx(e.ratios[here])   # the prediction until measured
    e.update(here, 2.0 * e.ratios[here])                   # twice what the model said
    assert e.estimate(here) == pytest.approx(2.0 * e.ratios[here])
    # The robot-wide scale is 2 and the neighbour's own evidence too: both say x2.
    assert e.estimate(near) == pytest.approx(2.0 * e.ratios[near])
    e.update(names[(-60, -20, -40, -20)], 1.0 * e.ratios[names[(-60, -20, -40, -20)]])
    # Two measurements (x2 here, x1 at (-60,-20)->(-40,-20)): a gait next to the x2 one leans
    # to 2, and the weights follow exp(-d^2 / (2 (20 deg)^2)) written out here.
    w_here = math.exp(-0.5 * (r(20) / r(20)) ** 2)         # near is 20 deg from here
    w_other = math.exp(-0.5 * (r(20) / r(20)) ** 2)        # and 20 deg from the other
    scale = (2.0 + 1.0) / 2
    want = (1.0 * scale + w_here * 2.0 + w_other * 1.0) / (1.0 + w_here + w_other)
    assert e.estimate(near) / e.ratios[near] == pytest.approx(want)
    if far is not None:
        assert e.source(far) == 'predicted x measured ratio nearby'
    assert e.source(here) == 'measured'


def test_a_live_lower_bound_below_the_need_is_kept_for_later_plans(predictor):
    ch = GaitChooser(predictor, sled_map('minirquad', 0.6), 1.0, PHIS, 0.95)
    energy = ch.energy_model(EnergyModel())
    first = ch.choose(2.94, energy)
    ch.observe(first.mode, 2.83)            # capacity_node at the measured pose: short
    again = ch.choose(2.94, energy)
    assert again.mode not in (None, first.mode)
    # Still good for a need it covers (the gaits cheaper than it left out).
    cheaper = [k for k in energy.ratios if energy.estimate(k) < energy.estimate(first.mode)]
    assert ch.choose(2.5, energy, exclude=cheaper).mode == first.mode
    assert 'DL' not in ch.modes and len(ch.modes) == 2  # its own table, not Table II's


@pytest.mark.slow
def test_the_burrowed_height_is_simulated_over_the_measured_legs(predictor):
    """The machine records the legs as the plant moved them during the planned burrow; the
    burrow simulation replays them (InlineReplayer: the same replay_burrow behavior_node's
    worker runs) and its pose becomes the height sent, modelled, with the plan's band.
    Reference: replay_burrow called here on the record the machine kept."""
    from rftgls_core.planning.replay import BurrowRecord, inputs_for_map, replay_burrow
    from rftgls_ros.behavior.replay import InlineReplayer
    gmap = sled_map('minirquad', 0.4)
    plant = Plant(0.4, predictor, gait_poses=GaitPoses.for_sled(0.4))
    cfg = fast_config(burrow_modes='planned', cycles=1, walk_time_s=2.5).check()
    replayer = InlineReplayer(inputs_for_map(gmap, 'minirquad'))
    m = BehaviorMachine(cfg, GaitChooser(predictor, gmap, 1.0, cfg.phis_rad,
                                         cfg.plan_confidence), replayer)
    seen = {}

    def watch(plant, machine):
        if machine.state == State.TUG and 'height' not in seen:
            seen['height'] = machine.height_input()
    run_loop(m, plant, t_max=60, on_step=watch)
    r = m.records[0]
    assert r.outcome == 'ok', [e['text'] for e in m.events][-10:]
    assert replayer.submitted == 1
    gait = m.chooser.gaits[r.mode]
    ref = replay_burrow(replayer.inputs, BurrowRecord.from_standing(m.burrow.record),
                        gait.pose)
    assert ref.pose is not None and len(m.burrow.record) >= 50
    h, band, source, prov = seen['height']
    assert prov is Provenance.MODELLED and 'measured leg samples' in source
    assert h == ref.pose.h_m and band == gait.pose.h_band_m
    ev = next(e for e in m.events if 'replayed over' in e['text'])
    assert ev['h_replay_m'] == h and ev['kind'] == 'info'
    print(f"replayed h {1e3 * h:.1f} mm, pitch {math.degrees(ev['theta_b_replay_rad']):.1f} "
          f"deg; plan {1e3 * gait.pose.h_m:.1f} mm, "
          f"{math.degrees(gait.pose.theta_b_rad):.1f} deg")


@pytest.mark.slow
def test_a_slow_replay_does_not_use_up_the_wait_for_capacity_node(predictor):
    """In a `make demo` run the replay of a planned burrow took most of CHECK's first 3 s;
    the height it settled was new to capacity_node, and CHECK, counting capacity_wait_s from
    its own start, aborted the attempt (estimate_other_height) at its first look at the
    evidence. The wait counts from the settled height: here the replay answers 1.5 s after
    capacity_wait_s and capacity_node takes 0.3 s to answer at the new height; the tug starts
    on an estimate at that height, nothing aborted."""
    from rftgls_core.planning.replay import inputs_for_map
    from rftgls_ros.behavior.replay import InlineReplayer
    gmap = sled_map('minirquad', 0.4)
    plant = Plant(0.4, predictor, gait_poses=GaitPoses.for_sled(0.4))
    cfg = fast_config(burrow_modes='planned', cycles=1, walk_time_s=2.5).check()

    class SlowReplayer(InlineReplayer):
        """The inline replay, answered capacity_wait_s + 1.5 s of plant time after submit."""
        ready_at = math.inf

        def submit(self, record, plan_pose):
            super().submit(record, plan_pose)
            self.ready_at = plant.t + cfg.capacity_wait_s + 1.5

        def result(self):
            return super().result() if plant.t >= self.ready_at else None

    m = BehaviorMachine(cfg, GaitChooser(predictor, gmap, 1.0, cfg.phis_rad,
                                         cfg.plan_confidence),
                        SlowReplayer(inputs_for_map(gmap, 'minirquad')))
    sent = {'h': None, 't': 0.0, 'old': None}

    def lagging(p):        # capacity_node answers at a new height 0.3 s after it is sent
        if p.h != sent['h']:
            sent.update(old=sent['h'], h=p.h, t=p.t)
        return sent['old'] if p.t - sent['t'] < 0.3 and sent['old'] is not None else p.h
    plant.estimate_height = lagging
    at_tug = []

    def watch(p, mach):
        if mach.state == State.TUG and not at_tug:
            at_tug.append((mach.obs.capacity_h, mach.height, mach.elapsed()))
    run_loop(m, plant, t_max=60, on_step=watch)
    texts = [e['text'] for e in m.events]
    assert [r.outcome for r in m.records] == ['ok'], texts[-8:]
    assert any('replayed over' in t for t in texts)
    assert at_tug and at_tug[0][0] == at_tug[0][1], at_tug
    check = next(e['t'] for e in m.events if e.get('to') == 'CHECK')
    tug = next(e['t'] for e in m.events if e.get('to') == 'TUG')
    assert tug - check >= cfg.capacity_wait_s + 1.5


class FixedReplayer:
    """A replay that answers `answer` (or nothing yet: None)."""

    def __init__(self, answer):
        self.answer, self.inputs, self.submitted = answer, None, 0

    def submit(self, record, plan_pose):
        self.submitted += 1

    def result(self):
        return self.answer

    def cancel(self):
        pass

    def close(self):
        pass


@pytest.mark.parametrize('case', ['agrees', 'within_imu', 'disagrees', 'no_pose', 'timeout'])
def test_the_replayed_pose_and_the_pitch_check_decide_the_height_sent(predictor, case):
    """At CHECK the replay of the burrow just made decides the height: its pose (modelled)
    when the measured pitch lies within its band plus pitch_check_tolerance_rad, assumed
    (the burrow did not go as modelled) beyond, and the plan's pose when the replay has none
    or takes longer than replay_timeout_s; each said in an event."""
    import dataclasses

    from rftgls_core.planning.replay import ReplayedBurrow
    from rftgls_ros.behavior import Observation
    cfg = fast_config(burrow_modes='planned', cycles=1).check()
    ch = GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0, cfg.phis_rad,
                     cfg.plan_confidence)
    d = ch.choose(1.96, ch.energy_model(EnergyModel()))
    plan = ch.gaits[d.mode].pose
    pose = dataclasses.replace(plan, h_m=plan.h_m + 0.004, source='replay')
    off = {'agrees': 0.0, 'within_imu': 0.5, 'disagrees': 3.0}.get(case, 0.0)
    answer = (None if case == 'timeout' else ReplayedBurrow(
        None if case == 'no_pose' else pose, 0.01, 'overturned' if case == 'no_pose' else '',
        100))
    m = BehaviorMachine(cfg, ch, FixedReplayer(answer))
    m.mode, m.state = d.mode, State.CHECK
    m.obs = Observation(t=30.0, theta_b=pose.theta_b_rad + pose.theta_b_band_rad
                        + math.radians(off))
    m.burrow.replay_since = 30.0 - (cfg.replay_timeout_s + 1 if case == 'timeout' else 1.0)
    assert m.burrow._replay_done()
    h, band, source, prov = m.height_input()
    texts = ' | '.join(e['text'] for e in m.events)
    if case in ('no_pose', 'timeout'):
        assert (h, band, prov) == (plan.h_m, plan.h_band_m, Provenance.MODELLED)
        assert "the plan's predicted pose stands" in texts
        return
    assert (h, band) == (pose.h_m, pose.h_band_m) and 'replay' in source
    assert prov is (Provenance.ASSUMED if case == 'disagrees' else Provenance.MODELLED)
    assert ('did not go as modelled' in texts) is (case == 'disagrees')
    # This node's own checks judge at the height it sends, over its band: not the plan's
    # (a demo run checked at the plan's 55.8 mm, whose band left the map, while it sent the
    # replay's 51.4 mm, and gave up an anchor capacity_node could have shown to hold).
    m.obs = dataclasses.replace(m.obs, legs=m.burrow_mode().final, t_legs=30.0)
    state = m.measured_state()
    assert state is not None and (state.h, m.anchor_height()[1]) == (h, band)


def planned_machine_in_burrow(predictor):
    """A planned-burrow machine (400 g) run with the plant until it enters BURROW: (machine,
    the plant's last observation)."""
    from rftgls_ros.behavior import Observation
    plant = Plant(0.4, predictor, gait_poses=GaitPoses.for_sled(0.4))
    cfg = fast_config(burrow_modes='planned', cycles=1).check()
    m = BehaviorMachine(cfg, GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0,
                                         cfg.phis_rad, cfg.plan_confidence))
    obs = Observation(t=0.0)
    while m.state != State.BURROW and plant.t < 30.0:
        plant.apply(m.step(obs))
        for _ in range(5):
            obs = plant.advance(0.002)
    assert m.state == State.BURROW
    return m, obs


STEP_S = 0.02     # behavior_node's step period (50 Hz)


def drive(m, obs, t_from, t_to, legs=None, **fields):
    """Step the machine in BURROW every STEP_S over (t_from, t_to] (s). The legs follow the
    last targets a step late (a servo that keeps up), or are ``legs(last_target)``; other
    Observation fields as given. Returns the last Commands."""
    from dataclasses import replace
    t, cmd, target = t_from, None, m.obs.legs
    while t < t_to - 1e-9:
        t = min(t + STEP_S, t_to)
        cmd = m.step(replace(obs, t=t, legs=target if legs is None else legs(target),
                             t_legs=t, t_tension=t, **fields))
        assert m.state == State.BURROW, m.reason
        target = cmd.legs if cmd.legs is not None else target
    return cmd


def burrow_from(m, obs, legs, tension=0.0):
    """Enter BURROW with the legs at `legs` (rad) and the tension (N); returns the time, s."""
    from dataclasses import replace
    m.obs = replace(obs, legs=legs, t_legs=obs.t, tension=tension)
    m.cycle.reel_lower_margin = math.inf
    m.go(State.BURROW, 'test: from where the walk left the legs')
    return m.obs.t


def test_a_planned_burrow_takes_up_the_slack_at_standing_before_its_stroke(predictor):
    """The plans simulate a rope just taut when the stroke starts (planning/replay.py, the
    Sled): with the legs at standing the winch reels in at take_up_speed_m_s until the
    tension reaches taut_tension_N, the ramp holding standing meanwhile; then the winch brakes
    and the stroke goes on. A rope that never goes taut stops the take-up after take_up_max_s,
    with a warning. The take-up is no tug: it is not booked against the need."""
    from rftgls_core.planning.gaits import STAND
    m, obs = planned_machine_in_burrow(predictor)
    cfg = m.cfg
    walked = tuple(x - math.radians(20.0) for x in STAND)
    t0 = burrow_from(m, obs, walked)
    assert drive(m, obs, t0, t0 + 0.1, legs=lambda q: walked, tension=0.0).winch == 0.0
    t_at = t0 + 1.5                                    # past the ramp's stand time
    cmd = drive(m, obs, t0 + 0.1, t_at, tension=0.0)
    assert cmd.winch == pytest.approx(cfg.take_up_speed_m_s) and m.burrow.taking_up
    cmd = drive(m, obs, t_at, t_at + 0.5, tension=0.1)
    assert cmd.winch == pytest.approx(cfg.take_up_speed_m_s)
    assert cmd.legs == pytest.approx(STAND)            # the stroke waits
    cmd = drive(m, obs, t_at + 0.5, t_at + 0.52, tension=cfg.taut_tension_N)
    assert cmd.winch == 0.0 and not m.burrow.taking_up
    assert any('tether taut' in e.get('text', '') for e in m.events)
    cmd = drive(m, obs, t_at + 0.52, t_at + 0.7, tension=cfg.taut_tension_N)
    assert cmd.legs != pytest.approx(STAND)            # the stroke goes on
    assert m.cycle.reel_lower_margin == math.inf       # the take-up was not booked
    # a rope that stays slack: the stroke starts after take_up_max_s, and says so
    t0 = burrow_from(m, obs, walked)
    assert drive(m, obs, t0, t0 + 1.5, tension=0.0).winch > 0.0
    t_up = m.burrow.take_up.t0
    assert drive(m, obs, t0 + 1.5, t_up + 0.5 * cfg.take_up_max_s, tension=0.0).winch > 0.0
    cmd = drive(m, obs, t_up + 0.5 * cfg.take_up_max_s, t_up + cfg.take_up_max_s + 0.02,
                tension=0.0)
    assert cmd.winch == 0.0 and not m.burrow.taking_up
    assert any('still slack' in e.get('text', '') for e in m.events)


def test_a_planned_burrow_has_dug_once_its_stroke_started(predictor):
    """`dug` (an outage then re-burrows off the dug sand, link_wait.py): not while the legs
    stand and the slack is taken up, from the stroke's start on."""
    from rftgls_core.planning.gaits import STAND
    m, obs = planned_machine_in_burrow(predictor)
    t0 = burrow_from(m, obs, STAND)
    drive(m, obs, t0, t0 + 0.3, tension=0.0)
    assert m.burrow.taking_up and not m.burrow.dug
    drive(m, obs, t0 + 0.3, t0 + 0.5, tension=m.cfg.taut_tension_N)
    assert not m.burrow.taking_up and m.burrow.dug


def test_a_planned_burrow_waits_at_standing_for_legs_to_rest_there(predictor):
    """The plan simulated its burrow from standing at rest: the ramp holds the standing pose
    until the measured legs rest there (within burrow_tolerance_rad for STAND_SETTLE_S),
    and goes on without them only LEG_WAIT_S after it got there. Legs swinging through
    standing (a walk the MCU has not stopped yet) do not start the burrow, and the replay's
    record starts where the legs rested."""
    from rftgls_core.planning.gaits import STAND
    from rftgls_ros.behavior.burrow import LEG_WAIT_S, STAND_SETTLE_S
    from rftgls_ros.behavior.gait_motion import stand_time
    m, obs = planned_machine_in_burrow(predictor)
    g, taut = m.planned_gait(), m.cfg.taut_tension_N    # the rope taut: no take-up
    walked = tuple(x - math.radians(20.0) for x in STAND)       # where a walk left the legs
    short = tuple(x - math.radians(7.0) for x in STAND)         # 7 deg short of standing
    t_stand = stand_time(walked, g.speed)

    def held(q):                                  # legs the sand holds short of standing
        return tuple(min(a, b) for a, b in zip(q, short))
    # legs that arrive late: held until 0.5 s past the stand time, then they rest there
    t0 = burrow_from(m, obs, walked, taut)
    t1 = t0 + t_stand + 0.5
    assert drive(m, obs, t0, t1, legs=held, tension=taut).legs == pytest.approx(STAND)
    cmd = drive(m, obs, t1, t1 + STAND_SETTLE_S, tension=taut)
    assert cmd.legs == pytest.approx(STAND)       # arrived, not yet at rest for long enough
    cmd = drive(m, obs, t1 + STAND_SETTLE_S, t1 + STAND_SETTLE_S + 0.1, tension=taut)
    assert cmd.legs != pytest.approx(STAND)       # the ramp goes on
    # legs that never arrive hold the ramp LEG_WAIT_S at most after it got to standing
    t0 = burrow_from(m, obs, walked, taut)
    t1 = t0 + t_stand + LEG_WAIT_S - STEP_S     # the ramp got to standing at t0 + t_stand
    assert drive(m, obs, t0, t1, legs=held, tension=taut).legs == pytest.approx(STAND)
    assert drive(m, obs, t1, t1 + 0.3, legs=held, tension=taut).legs != pytest.approx(STAND)
    # legs swinging through standing at 300 deg/s, then resting 60 deg behind it: the ramp
    # holds standing for them; they come back and rest there, and the burrow proper (the
    # record the replay follows) starts there, not at the swing
    swing = math.radians(300.0)
    t0 = burrow_from(m, obs, tuple(x + math.radians(60.0) for x in STAND), taut)
    t_swing = t0 + 1.5

    def walking(t):
        def legs(q):
            return tuple(x + max(math.radians(-60.0), math.radians(60.0) - swing * (t() - t0))
                         for x in STAND)
        return legs
    clock = {'t': t0}

    def now():
        clock['t'] += STEP_S
        return clock['t']
    cmd = drive(m, obs, t0, t_swing, legs=walking(now), tension=taut)
    assert cmd.legs == pytest.approx(STAND) and m.burrow.record_from is None
    cmd = drive(m, obs, t_swing, t_swing + 1.0, tension=taut)      # they follow the ramp
    assert cmd.legs != pytest.approx(STAND)
    start = m.burrow.record_from
    assert start is not None and start > t_swing
    first = next(s for s in m.burrow.record if s[0] >= start)
    assert max(abs(first[1] - STAND[0]), abs(first[2] - STAND[1])) \
        <= m.cfg.burrow_tolerance_rad


def test_a_planned_burrows_ramp_does_not_run_ahead_of_its_legs(predictor):
    """The ramp runs on its own clock (gait_motion.RampClock): after a step that came late
    (the node stalled) it goes on from where it stopped, not from where the wall clock got
    to; legs that stop following (a stalled link, MCU or servo) hold it within RAMP_LEAD_S
    of ramp (plus one step) of them, for LEG_WAIT_S at most. Either way the legs move along
    the plan's path at no more than the gait's speed."""
    from rftgls_core.planning.gaits import STAND
    from rftgls_ros.behavior.burrow import LEG_WAIT_S
    from rftgls_ros.behavior.gait_motion import RAMP_LEAD_S, RAMP_STEP_MAX_S
    m, obs = planned_machine_in_burrow(predictor)
    g, taut = m.planned_gait(), m.cfg.taut_tension_N
    tol = g.speed * RAMP_LEAD_S
    t0 = burrow_from(m, obs, STAND, taut)
    t1 = t0 + 0.4
    before = drive(m, obs, t0, t1, tension=taut).legs
    assert m.burrow.record_from is not None and before != pytest.approx(STAND)   # stroking

    def span(a, b):
        return max(abs(x - y) for x, y in zip(a, b))
    # a step 0.5 s late moves the targets by one capped step of the ramp
    after = drive(m, obs, t1 + 0.48, t1 + 0.5, legs=lambda q: before, tension=taut).legs
    assert 0.0 < span(before, after) <= g.speed * RAMP_STEP_MAX_S + 1e-12
    # legs that stop: the targets stay within the lead and one step of them
    stopped = after
    t2 = t1 + 0.5
    for k in range(1, int(0.9 * LEG_WAIT_S / STEP_S)):
        cmd = drive(m, obs, t2 + (k - 1) * STEP_S, t2 + k * STEP_S, legs=lambda q: stopped,
                    tension=taut)
        assert span(cmd.legs, stopped) <= tol + g.speed * STEP_S + 1e-12, k
    # ... for LEG_WAIT_S at most: then the ramp goes on without them
    t3 = t2 + LEG_WAIT_S + 0.3
    cmd = drive(m, obs, t2 + (k * STEP_S), t3, legs=lambda q: stopped, tension=taut)
    assert span(cmd.legs, stopped) > tol + g.speed * STEP_S


def test_a_planned_burrow_is_at_its_final_pose_only_once_it_ran_there(predictor):
    """The final pose counts once the ramp has run to it, for burrow_settle_s of the robot's
    own leg samples. A walk's stance sweeps the legs through -20 deg, the final pose of
    several gaits: legs left at the chosen gait's final pose, their stream late under load,
    once ended a burrow 0.6 s after it began, at the standing pose (`make test` on a fresh
    clone: one leg sample recorded, CHECK at legs -0.4 deg, the tug's slip detector stopped
    it). Here neither legs frozen there nor legs that stay there end the burrow early."""
    from dataclasses import replace

    from rftgls_ros.behavior.gait_motion import gait_duration
    m, obs = planned_machine_in_burrow(predictor)
    g, taut = m.planned_gait(), m.cfg.taut_tension_N
    # the leg stream stalls with the legs at the final pose, no new sample for longer than
    # burrow_settle_s (and shorter than input_timeout_s, after which the link wait takes over)
    stalled = int(m.cfg.input_timeout_s / STEP_S) - 1
    assert stalled * STEP_S > m.cfg.burrow_settle_s + STEP_S
    t0 = burrow_from(m, obs, g.final, taut)
    for k in range(1, stalled + 1):
        m.step(replace(obs, t=t0 + k * STEP_S, legs=g.final, t_legs=t0,
                       t_tension=t0 + k * STEP_S, tension=taut))
        assert m.state == State.BURROW, (k, m.reason)
    # fresh samples, the legs staying at the final pose (held there): BURROW until the ramp
    # has run its whole course
    t0 = burrow_from(m, obs, g.final, taut)
    course = gait_duration(g.final, g.retract, g.final, g.speed)
    drive(m, obs, t0, t0 + min(course, 1.0), legs=lambda q: g.final, tension=taut)
    assert m.burrow.record_from is None or m.burrow.ramp.t < course


def test_a_late_step_records_every_leg_sample_that_arrived_since_the_last(predictor):
    """behavior_node hands the machine every leg sample since its last step
    (Observation.leg_samples; 100 Hz from the bridge, a deep joint_states history): a planned
    burrow's record, which its replay follows, keeps each one even when a step runs late. (A
    first burrow was once replayed over 62 samples where the later ones had 95, and its
    replayed pitch missed the body's by 1.7 deg.) Without leg_samples a step records the
    latest legs, as the plant of these tests gives them."""
    from dataclasses import replace

    from rftgls_core.planning.gaits import STAND
    m, obs = planned_machine_in_burrow(predictor)
    record = m.burrow.record

    def step(t, legs, samples=()):
        m.step(replace(obs, t=t, legs=legs, t_legs=t, t_tension=t, leg_samples=list(samples)))
        assert m.state == State.BURROW, m.reason

    t1 = obs.t + 0.02
    n = len(record)
    step(t1, STAND)                                   # the latest legs only
    assert record[n:] == [(t1, *STAND)]
    # a step 0.5 s late: the 50 samples taken meanwhile, the newest also as the latest legs
    late = [(t1 + 0.01 * k, STAND[0] - 0.001 * k, STAND[1] + 0.001 * k) for k in range(1, 51)]
    n = len(record)
    step(late[-1][0], late[-1][1:], late)
    assert record[n:] == late
    # a sample already recorded is not recorded again
    n = len(record)
    newer = (late[-1][0] + 0.01, *STAND)
    step(newer[0], STAND, [late[-1], newer])
    assert record[n:] == [newer]


def test_a_replay_still_running_holds_the_check():
    from rftgls_ros.behavior import Observation
    cfg = fast_config(burrow_modes='planned', cycles=1).check()
    m = BehaviorMachine(cfg, GaitChooser(node_predictor(DEFAULT_MAP, robot=None, medium=None),
                                         sled_map('minirquad', 0.4), 1.0, cfg.phis_rad,
                                         cfg.plan_confidence), FixedReplayer(None))
    m.obs = Observation(t=5.0)
    m.burrow.replay_since = 4.0
    assert not m.burrow._replay_done() and m.replayed is None


@pytest.mark.slow
def test_a_slip_after_a_burrow_run_leg_by_leg_turns_the_simulated_body(predictor):
    """The simulator's scripted body settles at the gait map's pose and from then on moves only
    as the ground makes it: on sand 50 % weaker the 400 g planned anchor gives way along its
    RFT slip twist, which turns the body (|wy|/|v| ~2 rad/m there), into a pose that holds.
    (It used to be re-settled every step: p slid 425 mm without turning, unseen.)"""
    from minirquad_sim.ground import LiveGround
    plant = Plant(0.4, predictor, ground=LiveGround(medium_scale=0.5),
                  gait_poses=GaitPoses.for_sled(0.4))
    cfg = fast_config(burrow_modes='planned', cycles=1, walk_time_s=2.5).check()
    m = BehaviorMachine(cfg, GaitChooser(predictor, sled_map('minirquad', 0.4), 1.0,
                                         cfg.phis_rad, cfg.plan_confidence))
    pitch = []

    def watch(plant, machine):
        if machine.state == State.TUG:
            pitch.append(plant.robot.theta_b)
    run_loop(m, plant, t_max=60, on_step=watch)
    assert pitch and 0.0 < plant.tug_slip < 0.020, plant.tug_slip
    assert abs(pitch[-1] - pitch[0]) > math.radians(0.05)
    assert m.records[0].outcome == 'ok'


def test_a_replay_no_longer_wanted_is_not_waited_for():
    """ProcessReplayer, the worker behavior_node replays in: its answer is replay_burrow's
    in this process (the reference: the same function, same inputs, same CPU and thread
    count, so the same bits); a cancel or a close while a replay runs ends its worker at once
    instead of waiting out the replay (behavior_node's stop closes it: a wait there held the
    stop), and after a cancel the next replay is answered by a fresh worker."""
    import multiprocessing
    import time

    import numpy as np

    from rftgls_core.planning.burrowed import burrowed_pose
    from rftgls_core.planning.replay import BurrowRecord, inputs_for_map, replay_burrow
    from rftgls_ros.behavior.replay import ProcessReplayer
    gmap = sled_map('minirquad', 0.4)
    inputs = inputs_for_map(gmap, 'minirquad')
    answer = plan_from_map(gmap, PHIS, 0.0, 0.95).answers[0]
    plan = burrowed_pose(answer, 'plan')
    gait = answer.gait.burrow(inputs.multibody())
    record = BurrowRecord.of([(t, *gait.dof_reference(t)[0])
                              for t in np.arange(0.0, 5.0, 0.05)])
    here = replay_burrow(inputs, record, plan)
    assert here.pose is not None

    def answered(replayer: ProcessReplayer, timeout_s: float = 60.0):
        deadline = time.monotonic() + timeout_s
        while (r := replayer.result()) is None and time.monotonic() < deadline:
            time.sleep(0.01)
        return r

    def workers() -> set[int]:
        return {p.pid for p in multiprocessing.active_children()}

    replayer = ProcessReplayer(inputs)
    try:
        replayer.submit(record, plan)
        first = answered(replayer)
        assert first is not None and first.pose == here.pose
        t0 = time.monotonic()
        replayer.submit(record, plan)
        assert answered(replayer) is not None
        replay_s = time.monotonic() - t0         # one replay in the warm worker
        before = workers()
        replayer.submit(record, plan)
        replayer.cancel()                         # while it runs: its worker is ended
        assert before and not before & workers()
        replayer.submit(record, plan)
        assert answered(replayer).pose == here.pose
        replayer.submit(record, plan)
        t0 = time.monotonic()
        replayer.close()
        # a terminate and a join, not the rest of a replay; the same load slows both
        assert time.monotonic() - t0 < 0.5 * replay_s, replay_s
        assert workers() == set()
    finally:
        replayer.close()
