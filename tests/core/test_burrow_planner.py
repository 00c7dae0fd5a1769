"""The burrow planner (rftgls_core/planning): the front and the choice, the lower bound from
the runs of the spread, statuses of gaits that fail, the gait map against the live runs, and
`rftgls plan burrow`'s contract.

The map tests share one tiny map (SH tied to a 400 g sled, the inputs `rftgls plan
burrow --need-N 1.96 --phi 0,-20` asks for) built once per module; it takes ~10-20 s on a
loaded 2-core machine, the price of running the real simulation rather than a stand-in."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rftgls_core.cli.main import main as rftgls
from rftgls_core.maps.errors import MapFileError
from rftgls_core.multibody.servo import XL330_M077_5V
from rftgls_core.planning import gait_map
from rftgls_core.planning.bound import GaitAnswer, answer
from rftgls_core.planning.gaits import GaitPoint, table_ii_gaits
from rftgls_core.planning.plan import dominates, make_plan
from rftgls_core.planning.planner import plan_from_map
from rftgls_core.planning.predict import GaitRuns, PlanInputs, predict_gait
from rftgls_core.planning.spread import Spread, runs
from rftgls_core.rft.media import get_medium, medium_covariance

PHIS = (0.0, math.radians(-20.0))
SH = next(g for g in table_ii_gaits() if g.name == 'SH')
# SH's retracting pose, then the distal legs to 0 deg: a cheap tethered burrow (< 1 s)
SH0 = GaitPoint(SH.retract, (SH.final[0], 0.0), SH.speed)


def _inputs(sled_kg=0.4, stall=0.0, **kw) -> PlanInputs:
    m = get_medium('m90_sand')
    cov, src = medium_covariance(None, m.xi_n)
    return PlanInputs('minirquad', m, Spread.of(cov, src, stall), PHIS, sled_kg=sled_kg, **kw)


def _cli_inputs() -> PlanInputs:
    """What `rftgls plan burrow --need-N 1.96 --phi 0,-20` asks for (sled 0.40 kg from the
    need, the assumed medium spread, the servo tolerance)."""
    m = get_medium('m90_sand')
    cov, src = medium_covariance(None, m.xi_n)
    return PlanInputs('minirquad', m, Spread.of(cov, src), PHIS, sled_kg=0.4)


# ------------------------------------------------------------------ front and choice
def _answer(lower, energy, name='', status='assumed') -> GaitAnswer:
    g = GaitPoint((math.radians(-lower), 0.0), (0.0, math.radians(energy)), 1.0, name)
    ok = status == 'assumed'
    return GaitAnswer(g, status, '', np.zeros(4), np.zeros(2), energy if ok else None,
                      lower + 1.0 if ok else None, lower if ok else None, [])


def test_the_chosen_gait_is_the_cheapest_on_the_front_that_covers_the_need():
    rng = np.random.default_rng(3)
    answers = [_answer(float(lo), float(e)) for lo, e in rng.uniform(0.2, 5.0, (40, 2))]
    answers.append(_answer(9.0, 1.0, status='unsupported'))   # would dominate: no candidate
    plan = make_plan(answers, 2.0, 0.95, PHIS)
    cands = [a for a in answers if a.candidate]
    assert plan.chosen is not None and plan.chosen.lower_bound_N >= 2.0
    assert any(plan.chosen is f for f in plan.front)
    cheapest = min(a.energy_elec_J for a in cands if a.lower_bound_N >= 2.0)
    assert plan.chosen.energy_elec_J == cheapest
    for f in plan.front:      # nothing beats a front gait on both counts
        assert not any(dominates(b, f) for b in cands if b is not f)
    for a in cands:           # every other candidate is beaten by one on the front
        if not any(a is f for f in plan.front):
            assert any(dominates(f, a) for f in plan.front)
    assert all(a.candidate for a in plan.front)


def test_no_gait_covering_the_need_is_a_non_ok_plan_without_a_gait():
    plan = make_plan([_answer(1.0, 2.0), _answer(1.5, 3.0)], 1.96, 0.95, PHIS)
    assert plan.chosen is None and not plan.ok
    assert plan.status == 'unsupported' and plan.reason.startswith('need_not_covered')
    assert '1.5 N' in plan.reason
    assert plan.to_json()['chosen'] is None


# ------------------------------------------------------------------ the bound
def _runs(cap, pose=None, status=None) -> GaitRuns:
    cap = np.asarray(cap, dtype=float)
    R = len(cap)
    pose = np.tile([0.04, 0.05, -0.7, 0.5], (R, 1)) if pose is None else pose
    return GaitRuns(status or ['assumed'] * R, [''] * R, pose, np.full(R, 3.0), cap,
                    [[''] * cap.shape[1] for _ in range(R)], [(1, 2), (3, 4)],
                    [f'r{i}' for i in range(R)], PHIS)


def test_the_lower_bound_is_the_linear_band_and_never_above_a_run():
    cap = [[4.0, 4.2], [4.3, 4.5], [3.9, 4.1], [3.8, 4.4], [4.1, 4.0]]
    a = answer(SH, _runs(cap), 0.95)
    c = np.array(cap)
    # independent arithmetic: sigma from the two central differences, z(0.95) = 1.6449
    s0 = math.hypot((4.3 - 3.9) / 2, (3.8 - 4.1) / 2)
    s1 = math.hypot((4.5 - 4.1) / 2, (4.4 - 4.0) / 2)
    assert a.per_phi[0][1] == pytest.approx(s0)
    want = min(min(4.0 - 1.6448536 * s0, c[:, 0].min()), min(4.2 - 1.6448536 * s1,
                                                              c[:, 1].min()))
    assert a.lower_bound_N == pytest.approx(want, rel=1e-6)
    assert a.capacity_N == 4.0 and a.candidate
    # a capacity falling on both sides of the nominal (non-linear): the bound is the run's
    peak = answer(SH, _runs([[4.0, 4.0], [2.0, 4.0], [2.0, 4.0], [4.0, 4.0], [4.0, 4.0]]), 0.6)
    assert peak.lower_bound_N == 2.0


def test_a_run_without_a_pose_or_capacity_rules_the_gait_out():
    st = ['assumed', 'unsupported', 'not_run', 'not_run', 'not_run']
    r = _runs(np.full((5, 2), np.nan), status=st)
    r.reason[1] = 'overturned'
    a = answer(SH, r, 0.95)
    assert not a.candidate and a.status == 'unsupported' and 'overturned' in a.reason
    cap = np.full((5, 2), 4.0)
    cap[3, 1] = np.nan
    r = _runs(cap)
    r.cap_reason[3][1] = 'out_of_range: out_of_grid'
    a = answer(SH, r, 0.95)
    assert not a.candidate and a.status == 'out_of_range' and a.lower_bound_N is None


def test_the_spread_runs_follow_the_covariance_axes():
    m = get_medium('m90_sand')
    cov = np.array([[(0.1 * m.xi_n) ** 2, 0.5 * 0.1 * m.xi_n * 0.1],
                    [0.5 * 0.1 * m.xi_n * 0.1, 0.1 ** 2]])
    rs = runs(Spread.of(cov, 'calibrated', 0.1), m, XL330_M077_5V)
    assert len(rs) == 7 and rs[0].label == 'nominal'
    steps = np.array([[r.medium.xi_n - m.xi_n, r.medium.mu_surf - m.mu_surf] for r in rs[1:5]])
    # the +/- runs along the principal axes reproduce the covariance: sum of outer products
    back = sum(np.outer(s, s) for s in steps[::2])
    assert np.allclose(back, cov, rtol=1e-9)
    assert rs[5].servo.stall_torque == pytest.approx(1.1 * XL330_M077_5V.stall_torque)


# ------------------------------------------------------------------ simulated gaits
def test_an_overturning_gait_is_never_a_candidate():
    """Untethered, SH vaults over its nose (docs/design/walk-burrow-physics.md): status, no pose."""
    r = predict_gait(_inputs(sled_kg=0.0), SH)
    a = answer(SH, r, 0.95)
    assert r.status[0] == 'unsupported' and r.reason[0] == 'overturned'
    assert set(r.status[1:]) == {'not_run'}
    assert not a.candidate and a.lower_bound_N is None and 'overturned' in a.reason
    plan = make_plan([a], 0.5, 0.95, PHIS)
    assert plan.chosen is None and plan.to_json()['not_candidates'][0]['status'] == \
        'unsupported'


def test_a_run_past_its_step_budget_is_degenerate():
    r = predict_gait(_inputs(step_budget=40), SH0)
    assert r.status[0] == 'degenerate' and r.reason[0] == 'step_budget'
    assert not answer(SH0, r, 0.95).candidate


@pytest.fixture(scope='module')
def tiny_map(tmp_path_factory):
    inputs = _cli_inputs()       # the servo pair is copied: its line never binds in these
    gmap = gait_map.build_gait_map(inputs, [SH], workers=1)
    path = gait_map.save(tmp_path_factory.mktemp('gaits') / 'tiny.h5', gmap)
    return inputs, path


def test_a_map_answer_agrees_with_the_live_simulation(tiny_map):
    """The map stores the runs; a fresh live run of the same gait gives the same pose and
    capacity. Tolerance: both are the same float64 computation; only the RFT kernels'
    thread count can reorder a facet sum (1 ulp per facet, 1e-13 relative over ~3,000
    facets), and a burrow of ~500 steps carries it on at most linearly: 1e-9 m and 1e-9 N
    leave a margin of 10^3 (docs/design/burrow-planner.md, "The gait map")."""
    inputs, path = tiny_map
    gmap = gait_map.load(path)
    assert gmap.answers_for(inputs) is None
    stored = gmap.runs(PHIS)[0]
    # the nominal run and the +1 sigma run of the largest medium axis, simulated afresh (a
    # spread with only that axis: its nominal and + runs are the map's runs 0 and 1)
    step = inputs.spread.medium_axes()[0]
    one_axis = PlanInputs('minirquad', inputs.medium,
                          Spread.of(np.outer(step, step), 'assumed', 0.0), PHIS, sled_kg=0.4)
    live = predict_gait(one_axis, SH)
    for i in (0, 1):
        assert stored.status[i] == live.status[i] == 'assumed'
        assert np.allclose(stored.pose[i], live.pose[i], rtol=0.0, atol=1e-9)
        assert np.allclose(stored.capacity_N[i], live.capacity_N[i], rtol=0.0, atol=1e-9)
        assert stored.energy_elec_J[i] == pytest.approx(live.energy_elec_J[i], rel=1e-9)
    plan = plan_from_map(gmap, PHIS, 1.0, 0.95)
    assert plan.chosen is not None and plan.chosen.lower_bound_N >= 1.0


def test_a_map_answers_only_its_inputs_and_angles(tiny_map):
    inputs, path = tiny_map
    gmap = gait_map.load(path)
    assert 'inputs hash' in gmap.answers_for(_inputs(sled_kg=0.6))
    other = PlanInputs(inputs.robot, inputs.medium, inputs.spread, (math.radians(-10.0),),
                       sled_kg=0.4)
    assert 'phi' in gmap.answers_for(other)


def test_a_changed_map_is_refused(tiny_map, tmp_path):
    import h5py
    _, path = tiny_map
    bad = tmp_path / 'bad.h5'
    bad.write_bytes(path.read_bytes())
    with h5py.File(bad, 'r+') as f:
        cap = f['capacity_N'][()]
        f['capacity_N'][...] = cap * 2.0
    with pytest.raises(MapFileError, match='content hash'):
        gait_map.load(bad)


# ------------------------------------------------------------------ the command line
@pytest.mark.parametrize('argv', [
    ['--need-N', '1.96', '--phi', '0,120'],          # beyond straight up
    ['--need-N', '-1', '--phi', '0'],
    ['--need-N', '1.96', '--phi', '0', '--confidence', '1.5'],
    ['--need-N', '1.96', '--phi', '0,0'],
    ['--need-N', '1.96', '--phi', '0', '--sled', '-0.1'],
    ['--need-N', 'nan', '--phi', '0'],
])
def test_bad_inputs_are_refused(argv, capsys):
    assert rftgls(['plan', 'burrow', '--robot', 'minirquad', *argv, '--json']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'error' in err[0]


def test_the_command_plans_from_a_map_and_draws_the_front(tiny_map, tmp_path, capsys):
    _, path = tiny_map
    out = tmp_path / 'plan'
    code = rftgls(['plan', 'burrow', '--robot', 'minirquad', '--need-N', '1.96', '--phi',
                   '0,-20', '--map', str(path), '--json', '--out', str(out)])
    d = json.loads(capsys.readouterr().out)
    assert code == 0 and d['source']['kind'] == 'map'
    assert {'chosen', 'front', 'modes', 'elapsed_s'} <= set(d)
    keys = {'retract_deg', 'final_deg', 'pose', 'lower_bound_N', 'capacity_N', 'energy_elec_J'}
    assert keys <= set(d['chosen']) and all(keys <= set(f) for f in d['front'])
    assert d['chosen']['lower_bound_N'] >= 1.96 and d['chosen'] in d['front']
    assert d['chosen']['lower_bound_N'] <= d['chosen']['capacity_N']
    assert set(d['modes']) == {'SH'} and keys <= set(d['modes']['SH'])
    assert d['sled_kg'] == 0.4 and d['chosen']['pose']['provenance'] == 'modelled'
    assert (out / 'front.png').stat().st_size > 10_000
    assert json.loads((out / 'plan.json').read_text())['chosen'] == d['chosen']


def test_the_command_says_when_no_gait_covers_the_need(tiny_map, capsys):
    _, path = tiny_map
    # 100 N drags a 20 kg sled: the map for a 0.4 kg sled does not answer (exit 2), and with
    # --sled 0.4 it answers that no gait covers the need (exit 1)
    assert rftgls(['plan', 'burrow', '--need-N', '100', '--phi', '0,-20', '--map', str(path),
                   '--json']) == 2
    assert 'does not answer' in capsys.readouterr().err
    code = rftgls(['plan', 'burrow', '--need-N', '100', '--phi', '0,-20', '--map', str(path),
                   '--sled', '0.4', '--json'])
    d = json.loads(capsys.readouterr().out)
    assert code == 1 and d['status'] == 'unsupported' and d['chosen'] is None
    assert d['reason'].startswith('need_not_covered') and d['front']


@pytest.mark.parametrize('name, sled', list(zip(gait_map.SHIPPED['minirquad'], (0.4, 0.6))))
def test_the_shipped_gait_maps_answer_the_plans_they_are_for(name, sled):
    """Loaded against the hash recorded in the package, and answering for what `rftgls plan
    burrow --need-N 1.96|2.94 --phi 0,-20` asks (stale inputs: rebuild, maps/README.md)."""
    from rftgls_core.maps.shipped import maps_dir
    gmap = gait_map.load(maps_dir() / name)
    assert gait_map.SHIPPED_SHA256[name] == gmap.attrs['content_sha256']
    m = get_medium('m90_sand')
    cov, src = medium_covariance(None, m.xi_n)
    assert gmap.answers_for(PlanInputs('minirquad', m, Spread.of(cov, src), PHIS,
                                       sled_kg=sled)) is None
    assert {'DH', 'DL', 'SH'} <= set(gmap.arrays['gait_names'])


def test_the_shipped_400g_map_still_matches_the_simulation():
    """A change of the burrow simulation's physics leaves the inputs hash as it was: the
    shipped map would then answer with the old physics. Its stored nominal SH run must equal
    a fresh one (tolerance as in the live comparison above); if not, rebuild the shipped maps
    with the commands in maps/README.md."""
    from rftgls_core.maps.shipped import maps_dir
    name = gait_map.SHIPPED['minirquad'][0]
    gmap = gait_map.load(maps_dir() / name)
    k = list(gmap.arrays['gait_names']).index('SH')
    stored = gmap.runs(PHIS)[k]
    m = get_medium('m90_sand')
    cov, _src = medium_covariance(None, m.xi_n)
    step = np.linalg.eigh(cov)[1][:, -1] * math.sqrt(np.linalg.eigh(cov)[0][-1])
    one_axis = PlanInputs('minirquad', m, Spread.of(np.outer(step, step), 'assumed', 0.0),
                          PHIS, sled_kg=0.4)
    live = predict_gait(one_axis, SH)
    assert stored.status[0] == live.status[0], (stored.status[0], live.status[0])
    assert np.allclose(stored.pose[0], live.pose[0], rtol=0.0, atol=1e-9), \
        (stored.pose[0], live.pose[0], f'{name} is stale: rebuild it (maps/README.md)')
    assert np.allclose(stored.capacity_N[0], live.capacity_N[0], rtol=0.0, atol=1e-9)
