"""The lab tools take an anchor description: `--anchor FILE.yaml` of evaluate,
calibrate and replay poses that description instead of the bag's robot. The reference is the
preset path itself (RobotPredictor and Robot.pose, robots/), which the shipped description is
written from: the same bag analysed with the shipped description must give the preset's
numbers. A description the bags cannot feed, or one that cannot be read, is one line, exit 2."""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from tolerances import TWO_SOLVES_RTOL

from rftgls_core.description import shipped_description, state_values
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.types import AnchorState
from rftgls_ros.lab.bag_layout import read_pull_test
from rftgls_ros.lab.calibrate import main as calibrate_main
from rftgls_ros.lab.calibration import PullObservation, calibrate
from rftgls_ros.lab.evaluate import evaluate
from rftgls_ros.lab.evaluate import main as evaluate_main
from rftgls_ros.lab.predict import load_anchor, make_predictor

PROTOTYPE = shipped_description('prototype')


@pytest.fixture(scope='module')
def renamed(tmp_path_factory):
    """The shipped prototype with its height variable called `depth`: a description whose
    state variables are not the four a bag measures."""
    d = tmp_path_factory.mktemp('renamed')
    for name in ('prototype.urdf', 'c_leg.stl'):
        shutil.copy(PROTOTYPE.parent / name, d / name)
    text = PROTOTYPE.read_text().replace('height: h', 'height: depth').replace(
        '{name: h,', '{name: depth,')
    (d / 'renamed.yaml').write_text(text)
    return d / 'renamed.yaml'


@pytest.mark.parametrize('robot', ['prototype', 'minirquad'])
def test_surface_points_end_the_slip_where_the_body_plate_does(robot):
    """The shipped descriptions' surface_points are the body plate's ends: the stop height
    equals Robot.pose(...).plate_min_z at any pose (pitch both ways)."""
    desc = load_anchor(shipped_description(robot)).description
    rb = get_robot(robot)
    for h, tb in ((0.03, 0.0), (0.01, math.radians(20)), (0.004, math.radians(-25)),
                  (-0.02, math.radians(5))):
        st = AnchorState(h, tb, 0.0, 0.0)
        # two chains of rigid transforms of points ~0.1 m away: a few roundings, ~1e-17 m
        assert desc.surface_min_z(state_values(st)) == pytest.approx(
            rb.pose(st, 'backward').plate_min_z, abs=1e-12)


def test_evaluate_with_the_shipped_description_equals_the_bags_robot(synthetic_bags):
    tests = [read_pull_test(b) for b in synthetic_bags[:2]]
    kw = dict(step=2e-3, max_travel=0.012, integrator='euler', progress=False)
    rows0, preds0 = evaluate(tests, ['twist-mesh'], **kw)
    rows1, preds1 = evaluate(tests, ['twist-mesh'], anchor=load_anchor(PROTOTYPE), **kw)
    for a, b in zip(preds0['twist-mesh'], preds1['twist-mesh']):
        assert a.status == b.status == 'ok'
        # preset and description: two solves at every step (tests/tolerances.py). The
        # trajectory sums at most 6 Euler steps of 2 mm whose twists differ by that much,
        # and each pose feeds the next solve: 6 * 1e-9 per step, compounded, stays below 1e-7.
        assert b.breakaway_N == pytest.approx(a.breakaway_N, rel=TWO_SOLVES_RTOL)
        assert a.stop_reason == b.stop_reason and a.traj.shape == b.traj.shape
        assert np.allclose(b.traj, a.traj, rtol=1e-7, atol=1e-12, equal_nan=True)
    for a, b in zip(rows0, rows1):
        assert b.predicted['peak_N'] == pytest.approx(a.predicted['peak_N'], rel=TWO_SOLVES_RTOL)


def test_calibrate_with_the_shipped_description_equals_the_bags_robot(synthetic_bags):
    pulls = [PullObservation.from_test(read_pull_test(b)) for b in synthetic_bags[:3]]
    # three pull tests fix xi_n (mu_surf fixed keeps the fit short)
    med = get_medium('glass_beads')
    p0 = make_predictor('twist-mesh', 'prototype', med)
    p1 = make_predictor('twist-mesh', 'prototype', med, anchor=load_anchor(PROTOTYPE))
    for ob in pulls:
        a, b = (p.predict(ob.state, ob.phi, ob.pull) for p in (p0, p1))
        assert a.status == b.status and b.capacity_N == pytest.approx(a.capacity_N,
                                                                      rel=TWO_SOLVES_RTOL)
    c0 = calibrate(pulls, method='twist-mesh')
    c1 = calibrate(pulls, method='twist-mesh', anchor=load_anchor(PROTOTYPE))
    # least squares stops at xtol = ftol = 1e-10 (lab/calibrate.py) on residuals that differ
    # by 1e-9 (two solves): the two fits' parameters agree to ~1e-9 / curvature, and 1e-6
    # allows a curvature down to 1e-3 of the residual's scale.
    assert c1.xi_n == pytest.approx(c0.xi_n, rel=1e-6)
    assert c1.mu_surf == pytest.approx(c0.mu_surf, rel=1e-6)


def _one_line_exit_2(capsys, code: int, must: str) -> None:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and 'Traceback' not in err, err
    assert must in lines[0], lines[0]


@pytest.mark.parametrize('tool', ['evaluate', 'calibrate', 'replay'])
def test_a_bad_description_is_one_line_exit_2(tool, synthetic_bags, renamed, tmp_path, capsys):
    from rftgls_ros.lab.replay import main as replay_main
    bag = str(synthetic_bags[0])
    run = {'evaluate': lambda a: evaluate_main([bag, '--methods', 'twist-mesh', '--anchor', a,
                                                '--out-dir', str(tmp_path / 'e')]),
           'calibrate': lambda a: calibrate_main([bag, '--anchor', a,
                                                  '--out', str(tmp_path / 'm.json')]),
           'replay': lambda a: replay_main([bag, '--anchor', a])}[tool]
    _one_line_exit_2(capsys, run(str(tmp_path / 'nope.yaml')), 'nope.yaml')
    garbage = tmp_path / 'garbage.yaml'
    garbage.write_text('urdf: [unclosed\n')
    _one_line_exit_2(capsys, run(str(garbage)), 'garbage.yaml')
    # readable, but its state is not what a bag measures: the error names what is needed
    _one_line_exit_2(capsys, run(str(renamed)), 'h, theta_b, theta_l1, theta_l2')
    assert not (tmp_path / 'm.json').exists() and not (tmp_path / 'e').exists()


def test_replay_publishes_the_description(ros_context, synthetic_bags):
    """By default the bag's robot's shipped URDF, with --anchor that file's; latched, so a
    subscriber that joins later still gets it."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from rftgls_ros.lab.replay import (
        DESCRIPTION_TOPIC,
        LATCHED,
        bag_description,
        publish_description,
    )
    bag = synthetic_bags[0]
    default, explicit = bag_description(bag), bag_description(bag, PROTOTYPE)
    assert default is not None and default.sha256 == explicit.sha256
    node = rclpy.create_node('anchor_replay', context=ros_context)
    probe = rclpy.create_node('anchor_probe', context=ros_context)
    got: list = []
    ex = SingleThreadedExecutor(context=ros_context)
    try:
        publish_description(node, explicit)
        probe.create_subscription(String, DESCRIPTION_TOPIC, got.append, LATCHED)
        ex.add_node(node)
        ex.add_node(probe)
        for _ in range(200):
            if got:
                break
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
    assert got and got[0].data == (PROTOTYPE.parent / 'prototype.urdf').read_text()


def test_method_map_takes_a_described_map_with_its_description(tmp_path):
    """`--map` may be a described map (`rftgls map build --anchor`): it answers for --anchor
    (at a node: the live description solver's capacity, float32 storage) and is refused
    without it or for another description, in one line."""
    from rftgls_core.description import load_description
    from rftgls_core.maps.described import (
        description_grid,
        save_described_map,
    )
    from rftgls_core.maps.described_build import build_described_map
    desc = load_description(PROTOTYPE)
    med = get_medium('glass_beads')
    grid = description_grid(desc, {'h': [0.01, 0.02], 'theta_b': [0.0, 10.0],
                                   'theta_l1': [-40.0, -20.0], 'theta_l2': [0.0, 20.0]},
                            [0.0, 20.0], ('backward',))
    path = save_described_map(tmp_path / 'p.h5', build_described_map(desc, med, grid,
                                                                     method='twist-mesh'))
    m = make_predictor('map', 'prototype', med, path, anchor=load_anchor(PROTOTYPE))
    live = make_predictor('twist-mesh', 'prototype', med)
    st = AnchorState(0.02, math.radians(10.0), math.radians(-40.0), math.radians(20.0))
    a, b = live.predict(st, 0.0, 'backward'), m.predict(st, 0.0, 'backward')
    assert a.status == b.status and b.capacity_N == pytest.approx(a.capacity_N, rel=1e-6)
    with pytest.raises(ValueError, match='give --anchor'):
        make_predictor('map', 'prototype', med, path)
    with pytest.raises(ValueError, match='was built for description prototype'):
        make_predictor('map', 'prototype', med, path,
                       anchor=load_anchor(shipped_description('minirquad')))


def test_synthetic_bags_of_the_shipped_description_are_the_robots():
    """`synthetic --anchor prototype.yaml` simulates the preset's pull (same samples to 1e-9
    relative: the same model, the same stop) and records the description in the notes."""
    from rftgls_ros.lab.synthetic import synthesize
    state = AnchorState.from_degrees(0.02, 0.0, -20.0, 20.0)
    truth, nominal = get_medium('glass_beads'), get_medium('glass_beads')
    kw = dict(step=2e-3, max_travel=0.012, integrator='euler', seed=3)
    a = synthesize(state, 'backward', truth, nominal, **kw)
    b = synthesize(state, 'backward', truth, nominal, anchor=load_anchor(PROTOTYPE), **kw)
    assert b.meta.robot == a.meta.robot == 'prototype'
    assert 'anchor description prototype' in b.meta.notes
    # two solves per sample (tests/tolerances.py); the pose integrates them like above
    assert np.allclose(b.tension_N, a.tension_N, rtol=TWO_SOLVES_RTOL, atol=1e-12)
    assert np.allclose(b.pose, a.pose, rtol=TWO_SOLVES_RTOL, atol=1e-12)


def test_synthetic_refuses_a_bad_description_in_one_line(renamed, tmp_path, capsys):
    from rftgls_ros.lab.synthetic import main as synthetic_main
    code = synthetic_main(['--out-dir', str(tmp_path / 's'), '--anchor', str(renamed)])
    _one_line_exit_2(capsys, code, 'h, theta_b, theta_l1, theta_l2')
    assert not (tmp_path / 's').exists()


def test_a_rigid_anchor_is_fed_by_anchor_state(tmp_path, capsys):
    """The example ellipsoid (state depth, tilt) is refused by name alone, and with
    --anchor-state depth=h,tilt=theta_b a synthetic pull of it starts at the description's
    capacity (reference: rftgls_core's DescriptionPredictor at that pose, fed the same way)."""
    from pathlib import Path

    from rftgls_core.description import load_description
    from rftgls_core.predictor.live import DescriptionPredictor
    from rftgls_ros.lab.synthetic import SensorModel, synthesize
    ell = Path(__file__).resolve().parents[2] / 'examples' / 'anchors' / 'ellipsoid.yaml'
    with pytest.raises(ValueError, match='--anchor-state'):
        load_anchor(ell)
    with pytest.raises(ValueError, match='needs --anchor'):
        load_anchor(None, 'depth=h')
    anchor = load_anchor(ell, 'depth=h,tilt=theta_b')
    assert anchor.state_map == {'depth': 'h', 'tilt': 'theta_b'}
    med = get_medium('glass_beads')
    state = AnchorState(-0.055, math.radians(-30.0), 0.0, 0.0)
    test = synthesize(state, 'backward', med, med, phi=math.radians(45.0), step=2e-3,
                      max_travel=0.004, integrator='euler', anchor=anchor,
                      sensors=SensorModel(tension_sigma_N=0.0))
    ref = DescriptionPredictor(load_description(ell), med, method='twist-mesh',
                               state_map={'depth': 'h', 'tilt': 'theta_b'})
    want = ref.predict(state, math.radians(45.0), 'backward').capacity_N
    assert test.meta.robot == 'ellipsoid_anchor'
    assert float(test.tension_N[np.searchsorted(test.force_t, 1.0)]) == pytest.approx(
        want, rel=1e-6)
