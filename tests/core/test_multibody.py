"""The whole-robot simulation: its RFT evaluation is the engine's, every step balances, a tug
follows `rftgls simulate pull`, a described robot burrows, bad gaits are refused."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from rftgls_core.cli.main import main as rftgls
from rftgls_core.description import load_description
from rftgls_core.geometry.mesh import Facets
from rftgls_core.multibody import balance
from rftgls_core.multibody.contact import Contact
from rftgls_core.multibody.described import from_description
from rftgls_core.multibody.gaits import BurrowGait, GaitError, HoldGait
from rftgls_core.multibody.robot import BasePose, from_preset
from rftgls_core.multibody.simulate import STILL, SimOptions, Simulator
from rftgls_core.multibody.sled import Rope, Sled
from rftgls_core.multibody.validate import check_gait
from rftgls_core.predictor import PredictorSpec, build_predictor
from rftgls_core.rft.engine import BuriedBody
from rftgls_core.rft.media import get_medium
from rftgls_core.rft.models import make_model
from rftgls_core.robots.presets import minirquad
from rftgls_core.sim.trajectory import simulate_pull
from rftgls_core.types import AnchorState, Status
from tests.core.multibody_robots import write_robot

SAND = get_medium('m90_sand')
# A leg stops where its loop's command kp x error falls below the servo's smallest goal
# velocity (simulate.STILL): within STILL / kp of its reference.
HOLD_DEG = math.degrees(STILL / SimOptions().kp) + 1e-9


def deg(*a):
    return tuple(math.radians(v) for v in a)


def test_packed_parts_are_the_engines_wrenches():
    """Each part's wrench from the packed evaluation equals BuriedBody.planar_wrench on that
    part's facets with its own twist (the same kernel arithmetic per facet; only the summation
    order across parts differs, so 1e-12 of the largest wrench bounds it)."""
    robot = from_preset(minirquad())
    posed = robot.pose(BasePose(0.0, 0.04, math.radians(5.0)), np.radians([-40, 30, -40, 10]))
    rates = np.array([0.5, -0.3, 0.5, 0.2])        # the right distal leg out of step: 3 parts
    model = make_model('agarwal', SAND)
    contact = Contact(posed, model, rates)
    assert [pt.legs for pt in contact.parts] == [(0, 2), (1,), (3,)]
    xs = np.random.default_rng(3).normal(size=(40, 3)) * [0.05, 0.05, 0.5]
    got = contact.part_wrenches(xs)
    for j, pt in enumerate(contact.parts):
        facets = Facets.concatenate([posed.legs[i] for i in pt.legs])
        body = BuriedBody(facets, model, ref=posed.ref)
        ref = body.planar_wrench(xs + pt.rate * pt.jac, use_symmetry=False)
        assert np.abs(got[:, j] - ref).max() <= 1e-12 * np.abs(ref).max()


def test_ramped_wrenches_are_the_reference_and_a_nan_twist_stays_nan():
    """The compiled ramped path the root searches use (eps and creep > 0; SIMD lanes over
    the facets) against evaluate.py's numpy reference. Both sum the same per-facet products;
    the compiled one may fuse a multiply-add (one rounding instead of two, <= 1 ulp per
    product), so with ~200 facets a part's sum differs by at most ~200 ulp of its largest
    term: 1e-12 of the largest wrench bounds it. A twist that is not finite gives NaN, never
    a wrench of zero from facets whose weight is 0."""
    from rftgls_core.multibody import evaluate
    robot = from_preset(minirquad())
    posed = robot.pose(BasePose(0.0, 0.04, math.radians(5.0)), np.radians([-40, 30, -40, 10]))
    contact = Contact(posed, make_model('agarwal', SAND), np.array([0.5, -0.3, 0.5, 0.2]))
    pk = contact.packed
    xs = np.random.default_rng(4).normal(size=(40, 3)) * [0.05, 0.05, 0.5]
    xs[:5] *= 1e-6                                      # slower than creep: a fraction
    for eps, creep in ((1e-3, 1e-5), (3e-2, 1e-5), (1e-2, 0.0)):
        got = contact.part_wrenches(xs, eps, creep=creep)
        ref = evaluate._numpy(pk._bound, pk.pid, pk.n_parts, xs, contact._offsets, eps,
                              creep) * pk.counts[None, :, None]
        assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max(), (eps, creep)
    bad = np.array([[np.nan, 0.0, 0.0], [np.inf, 0.0, 0.0]])
    assert np.isnan(contact.part_wrenches(bad, 1e-3, creep=1e-5)).any(axis=(1, 2)).all()


@pytest.fixture(scope='module')
def sh_burrow():
    """The paper's SH burrow, tied to a 400 g sled (without it the retracting stroke rolls
    the robot forward onto its nose: docs/design/walk-burrow-physics.md)."""
    robot = from_preset(minirquad())
    gait = BurrowGait(robot, (0.0, 0.0), deg(-40, -20), deg(-40, 30), duration=3.0)
    return robot, Simulator(robot, SAND, sled=Sled(0.4)).run(gait)


def test_every_step_balances(sh_burrow):
    """Every step of a burrow solves its balance to RESIDUAL_TOL of the weight (stated in
    balance.py: Newton on the ramped closure; round-off of a few wrench sums of ~weight size
    sits near 1e-15 of it)."""
    robot, res = sh_burrow
    assert res.status is Status.ASSUMED, res.detail
    tol = balance.RESIDUAL_TOL * robot.weight
    assert len(res.samples) > 100
    assert max(s.residual for s in res.samples) <= tol


def test_burrow_reaches_its_pose_and_reports(sh_burrow):
    robot, res = sh_burrow
    s = res.summary()
    assert s['theta_l1_deg'] == pytest.approx(-40.0, abs=HOLD_DEG)
    assert s['theta_l2_deg'] == pytest.approx(30.0, abs=HOLD_DEG)
    assert s['h_m'] < s['start']['h_m']           # the legs went into the sand
    assert s['energy_elec_J'] > s['energy_mech_J'] > 0.0
    assert set(s['phases']) == {'retract', 'dwell', 'final', 'hold'}
    # the servo torques hold the legs: each a share of the weight's moment about its hip
    last = res.samples[-1]
    assert np.all(np.abs(last.torques) < robot.weight * 0.1)


def test_rope_pulls_up_to_the_sled_friction():
    """Just taut at the start; a stretch pulls k x stretch along the rope; past mu m g the sled
    slides toward p and the pull stays mu m g."""
    sled = Sled(0.4, mu=0.5, distance=0.5, height=0.0, stiffness=400.0)
    rope = Rope(sled, 0.0, 0.0)
    assert rope.pull(0.0, 0.0)[0] == 0.0
    t, phi = rope.pull(0.002, 0.0)                 # 2 mm forward: 0.8 N pulling back (-x)
    assert t == pytest.approx(0.8) and phi == pytest.approx(0.0)
    t, _ = rope.pull(0.100, 0.0)
    assert t == pytest.approx(sled.friction) and rope.moved > 0.09
    assert rope.pull(0.100, 0.0)[0] == pytest.approx(sled.friction)   # no further slide
    assert rope.pull(0.090, 0.0)[0] == 0.0          # slack once p comes back


def test_tug_agrees_with_simulate_pull():
    """A tether pulled slowly past the anchor's capacity: the robot's slip path (height and
    pitch of p against its travel) is `rftgls simulate pull`'s from the same state. Both solve
    the same balance on the same RFT; they differ by the multibody's creep (1e-5 m/s: the
    resting parts' share), inertia while the tension rises (0.5 N/s) and its time steps, each
    measured to move the path by less than the 0.05 mm and 0.05 deg allowed here."""
    rm = minirquad()
    robot = from_preset(rm)
    pose = deg(-40, 30)
    gait = HoldGait(robot, pose, tension=4.0, phi=0.0, ramp=8.0, duration=7.0)
    res = Simulator(robot, SAND, options=SimOptions(dt=0.01)).run(gait)
    s0 = res.samples[0]
    start = AnchorState(s0.z, s0.theta_b, *pose)
    model = build_predictor(PredictorSpec(robot='minirquad', medium=SAND, live_method='direct'))
    traj = simulate_pull(model, start, 0.0, 'backward',
                         lambda st: rm.pose(st, 'backward').plate_min_z, step=1e-3,
                         max_travel=0.01).as_array()
    x = np.array([s.px for s in res.samples]) - s0.px
    z = np.array([s.pz for s in res.samples])
    th = np.array([s.theta_b for s in res.samples])
    assert x.min() < -0.01, 'the robot slipped less than 10 mm'
    order = np.argsort(x)
    for _, px, pz, pth, _ in traj[1:]:
        assert np.interp(px, x[order], z[order]) == pytest.approx(pz, abs=5e-5)
        assert np.interp(px, x[order], th[order]) == pytest.approx(pth, abs=math.radians(0.05))


def test_a_described_robot_burrows(tmp_path):
    """A robot that is no preset (its own URDF + YAML: a box body, smaller C-legs) burrows:
    it settles, its legs reach the final pose, every step balances."""
    desc = load_description(write_robot(tmp_path))
    robot = from_description(desc)
    assert robot.dof_names == ('theta_rear', 'theta_front')
    assert robot.base is not None and robot.mass == pytest.approx(0.2)
    assert [leg.twin for leg in robot.legs] == [2, 3, 0, 1]
    gait = BurrowGait(robot, (0.0, 0.0), deg(-50, -30), deg(-30, 20), duration=2.5)
    check_gait(robot, gait)
    res = Simulator(robot, SAND).run(gait)
    assert res.status is Status.ASSUMED, res.detail
    s = res.summary()
    assert s['theta_rear_deg'] == pytest.approx(-30.0, abs=HOLD_DEG)
    assert s['theta_front_deg'] == pytest.approx(20.0, abs=HOLD_DEG)
    assert res.max_residual() <= balance.RESIDUAL_TOL * robot.weight


def test_joint_outside_its_range_is_refused(tmp_path):
    desc = load_description(write_robot(tmp_path, limits=(-1.0, 1.0)))
    robot = from_description(desc)
    assert robot.legs[0].limits == (-1.0, 1.0)
    gait = BurrowGait(robot, (0.0, 0.0), deg(-75, -30), deg(-30, 20))
    with pytest.raises(GaitError, match='outside its range'):
        check_gait(robot, gait)


def test_leg_through_the_body_is_refused(tmp_path):
    """Legs hinged under the body and inside its width (|y| 20 mm < 35 mm): turning the front
    legs up drives them through it; turning them so the arc stays below it does not (the C
    leaves its hip level, so toes backward would tip the arc's start into the body)."""
    robot = from_description(load_description(write_robot(tmp_path, leg_y=0.020)))
    with pytest.raises(GaitError, match='through the body'):
        check_gait(robot, BurrowGait(robot, (0.0, 0.0), deg(-30, 180), deg(-30, 180)))
    check_gait(robot, BurrowGait(robot, (0.0, 0.0), deg(20, 20), deg(30, 40)))


def test_time_step_too_coarse_is_a_status():
    robot = from_preset(minirquad())
    gait = BurrowGait(robot, (0.0, 0.0), deg(-40, -20), deg(-40, 30), duration=3.0)
    res = Simulator(robot, SAND, options=SimOptions(dt=2.0, max_substeps=8)).run(gait)
    assert res.status is Status.INVALID_INPUT and res.reason == 'step_too_coarse'
    assert res.summary()['h_m'] is None


def test_no_support_is_a_status(tmp_path):
    """Legs pointing up and no base mesh: put down, nothing ever holds the robot."""
    robot = from_description(load_description(write_robot(tmp_path, base_mesh=False)))
    gait = BurrowGait(robot, deg(180, 180), deg(180, 180), deg(180, 180), duration=1.0)
    res = Simulator(robot, SAND, options=SimOptions(settle_time=0.3)).run(gait)
    assert res.status is Status.UNSUPPORTED
    assert res.reason in ('no_rest', 'base_in_sand')


def test_an_overturning_burrow_is_a_status():
    """The paper's DH burrow without a tether: the final stroke vaults the robot over its nose
    (docs/design/walk-burrow-physics.md). Past a quarter turn of pitch the run stops with a
    reason, and no final pose or energy is reported as if it were an anchor."""
    robot = from_preset(minirquad())
    gait = BurrowGait(robot, (0.0, 0.0), deg(-75, -50), deg(-40, 30))
    res = Simulator(robot, SAND).run(gait)
    assert res.status is Status.UNSUPPORTED and res.reason == 'overturned', res.detail
    assert abs(res.samples[-1].theta_b) > math.pi / 2
    s = res.summary()
    assert s['h_m'] is None and s['theta_b_deg'] is None and s['energy_elec_J'] is None


def test_the_burrow_command_prints_its_pose_and_writes_its_files(tmp_path, capsys):
    """`rftgls simulate burrow --json --out DIR`: the keys the command line promises
    (docs/cli.md), the files it writes, and the exit status of a run with a value."""
    out = tmp_path / 'sh'
    code = rftgls(['simulate', 'burrow', '--robot', 'minirquad', '--mode', 'SH', '--sled', '0.4',
                   '--duration', '3', '--json', '--out', str(out)])
    s = json.loads(capsys.readouterr().out)
    assert code == 0 and s['status'] == 'assumed'
    for key in ('h_m', 'theta_b_deg', 'theta_l1_deg', 'theta_l2_deg', 'stalled',
                'energy_mech_J', 'energy_elec_J', 'elapsed_s'):
        assert key in s
    assert s['theta_l2_deg'] == pytest.approx(30.0, abs=HOLD_DEG)
    with open(out / 'trajectory.csv', newline='') as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == s['steps']
    assert float(rows[-1]['p_z_m']) == s['h_m']
    assert json.loads((out / 'summary.json').read_text())['h_m'] == s['h_m']
    assert (out / 'run.png').stat().st_size > 0


def test_an_overturning_burrow_command_prints_no_pose(capsys):
    code = rftgls(['simulate', 'burrow', '--mode', 'SH', '--duration', '3', '--json'])
    s = json.loads(capsys.readouterr().out)
    assert code == 0 and s['status'] == 'unsupported' and s['reason'] == 'overturned'
    assert s['h_m'] is None and s['energy_elec_J'] is None
