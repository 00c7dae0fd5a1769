"""capacity_node's live solver and the simulator's true ground on an anchor description: the
shipped descriptions give the numbers of the robot presets, a map
built for another robot is refused, a description the node cannot estimate is refused in one
line. No ROS needed (the predictor and ground are built the way the node and simulator do)."""
from __future__ import annotations

import math

import pytest
from tolerances import TWO_SOLVES_RTOL, TWO_SOLVES_TWIST_ATOL

from minirquad_sim.ground import LiveGround, slip_per_m
from minirquad_sim.main import build_parser
from rftgls_core.cli.demo import ANCHOR_MODES
from rftgls_core.description import shipped_description
from rftgls_core.description_writer import write_robot_description
from rftgls_core.predictor.live import DescriptionPredictor, RobotPredictor
from rftgls_node_base.parameters import ConfigError
from rftgls_ros.capacity.node_predictor import node_predictor
from rftgls_ros.capacity.params import DEFAULTS

MINIRQUAD = str(shipped_description('minirquad'))


@pytest.mark.parametrize('method', ['direct', 'twist-mesh'])
def test_the_shipped_description_gives_the_live_predictor_numbers(method):
    ref = node_predictor('', method, 'minirquad', 'm90_sand', 0, 'backward')
    desc = node_predictor('', method, 'minirquad', 'm90_sand', 0, 'backward',
                          anchor_description_file=MINIRQUAD)
    assert isinstance(ref, RobotPredictor) and isinstance(desc, DescriptionPredictor)
    for state in ANCHOR_MODES.values():          # Table II: DH, DL, SH
        for pull in ('backward', 'forward'):
            for phi in (0.0, math.radians(-20.0)):
                a, b = ref.predict(state, phi, pull), desc.predict(state, phi, pull)
                assert a.status == b.status
                if a.capacity_N is None:
                    assert b.capacity_N is None
                    continue
                # preset and description: two solves (tests/tolerances.py)
                assert b.capacity_N == pytest.approx(a.capacity_N, rel=TWO_SOLVES_RTOL,
                                                     abs=1e-12)
                assert b.slip_twist == pytest.approx(a.slip_twist, abs=TWO_SOLVES_TWIST_ATOL)


def test_the_default_parameter_keeps_the_robot_shortcut():
    assert DEFAULTS['anchor_description_file'] == ''


def test_a_map_for_another_description_is_refused():
    proto = str(shipped_description('prototype'))
    with pytest.raises(ConfigError, match='does not answer for anchor_description_file'):
        node_predictor('minirquad', robot='minirquad', medium='m90_sand',
                       anchor_description_file=proto)
    # the robot's own description is accepted with its shipped map
    node_predictor('minirquad', robot='minirquad', medium='m90_sand',
                   anchor_description_file=MINIRQUAD)


def test_a_description_the_node_cannot_estimate_is_one_line(tmp_path):
    write_robot_description('minirquad', tmp_path)
    yml = (tmp_path / 'minirquad.yaml').read_text().replace('name: theta_b,', 'name: pitch,')
    (tmp_path / 'renamed.yaml').write_text(yml.replace('pitch: theta_b', 'pitch: pitch'))
    with pytest.raises(ConfigError, match='estimates h, theta_b') as err:
        node_predictor('', anchor_description_file=str(tmp_path / 'renamed.yaml'))
    assert '\n' not in str(err.value)
    with pytest.raises(ConfigError, match='anchor_description_file: .*cannot read'):
        node_predictor('', anchor_description_file=str(tmp_path / 'missing.yaml'))


def test_the_sim_ground_on_the_shipped_description_is_the_preset_ground():
    args = build_parser().parse_args(['--anchor', MINIRQUAD])
    assert args.anchor == MINIRQUAD
    preset = LiveGround(method='twist-mesh', fallback_method=None)
    described = LiveGround(method='twist-mesh', fallback_method=None, anchor=MINIRQUAD)
    assert 'anchor description' in described.describe()
    for state in ANCHOR_MODES.values():
        for phi in (0.0, math.radians(-20.0)):
            a = preset.predict(state, phi, 'backward')
            b = described.predict(state, phi, 'backward')
            assert a.status == b.status
            if a.capacity_N is not None:
                assert b.capacity_N == pytest.approx(a.capacity_N, rel=TWO_SOLVES_RTOL)
                # per metre of travel: the unit twist over |(vx, vz)|, near 1 for these pulls
                assert slip_per_m(b) == pytest.approx(slip_per_m(a), abs=TWO_SOLVES_TWIST_ATOL)
    # the mass scale reaches the described ground too (a heavier robot holds more)
    heavy = LiveGround(method='twist-mesh', fallback_method=None, anchor=MINIRQUAD,
                       mass_scale=1.5)
    dh = ANCHOR_MODES['DH']
    light = described.predict(dh, 0.0, 'backward').capacity_N
    assert light is not None and heavy.predict(dh, 0.0, 'backward').capacity_N > light


def test_the_warm_live_method_name_gives_the_cold_direct_on_a_description():
    # integ's default live_method is 'direct-warm' (the cold direct's answers, warm-started)
    p = node_predictor('', 'direct', anchor_description_file=MINIRQUAD)
    q = node_predictor('', 'direct-warm', medium='m90_sand', anchor_description_file=MINIRQUAD)
    dh = ANCHOR_MODES['DH']
    assert q.method == 'direct'
    assert q.predict(dh, 0.0, 'backward').capacity_N == p.predict(dh, 0.0, 'backward').capacity_N


def renamed_minirquad(folder) -> str:
    """The shipped MiniRQuad description written to `folder` with its state variables renamed
    (h, theta_b, theta_l1, theta_l2 -> height, pitch, hip_a, hip_b); the YAML's path."""
    write_robot_description('minirquad', folder)
    yml = (folder / 'minirquad.yaml').read_text()
    for old, new in (('h', 'height'), ('theta_b', 'pitch'), ('theta_l1', 'hip_a'),
                     ('theta_l2', 'hip_b')):
        yml = yml.replace(f'{{name: {old},', f'{{name: {new},')
    yml = yml.replace('height: h', 'height: height').replace('pitch: theta_b', 'pitch: pitch')
    (folder / 'renamed.yaml').write_text(yml)
    return str(folder / 'renamed.yaml')


def test_other_variable_names_are_fed_by_anchor_state_variables(tmp_path):
    """The MiniRQuad description with its variables renamed (height, pitch, hip_a, hip_b) is
    refused by name alone, in one line naming the estimates and their topics; mapped with
    anchor_state_variables it answers the shipped description's numbers exactly."""
    path = renamed_minirquad(tmp_path)
    with pytest.raises(ConfigError) as err:
        node_predictor('', 'twist-mesh', anchor_description_file=path)
    msg = str(err.value)
    assert '\n' not in msg and 'h <- height_topic' in msg and 'theta_l1 <- joint_states' in msg
    assert 'height, pitch, hip_a, hip_b' in msg
    mapped = node_predictor(
        '', 'twist-mesh', anchor_description_file=path,
        anchor_state_variables='height=h, pitch=theta_b, hip_a=theta_l1, hip_b=theta_l2')
    ref = node_predictor('', 'twist-mesh', anchor_description_file=MINIRQUAD)
    for state in ANCHOR_MODES.values():
        a, b = ref.predict(state, 0.0, 'backward'), mapped.predict(state, 0.0, 'backward')
        assert a.status == b.status and a.capacity_N == b.capacity_N
    # swapping the legs is a different robot: the answers must change (the map is used)
    swapped = node_predictor(
        '', 'twist-mesh', anchor_description_file=path,
        anchor_state_variables='height=h, pitch=theta_b, hip_a=theta_l2, hip_b=theta_l1')
    dh = ANCHOR_MODES['DH']
    assert swapped.predict(dh, 0.0, 'backward').capacity_N != \
        ref.predict(dh, 0.0, 'backward').capacity_N


@pytest.mark.parametrize('text, must', [
    ('height=h,pitch=theta_b,hip_a=theta_l1', 'hip_b have no quantity'),
    ('height=h,pitch=h,hip_a=theta_l1,hip_b=theta_l2', 'h feeds two state variables'),
    ('height=z,pitch=theta_b', 'ESTIMATE one of h, theta_b'),
    ('height', 'want NAME=ESTIMATE'),
    ('depth=h,height=h', 'no state variable depth'),
])
def test_a_bad_state_variable_map_is_one_line(text, must, tmp_path):
    with pytest.raises(ConfigError) as err:
        node_predictor('', 'twist-mesh', anchor_description_file=renamed_minirquad(
            tmp_path), anchor_state_variables=text)
    assert '\n' not in str(err.value) and must in str(err.value), str(err.value)
    with pytest.raises(ConfigError, match='needs anchor_description_file'):
        node_predictor('', 'twist-mesh', anchor_state_variables='h=h')


def test_a_two_variable_body_uses_h_and_theta_b_only(tmp_path):
    """An ellipsoid anchor with state (depth, tilt), mapped depth=h, tilt=theta_b: the node's
    leg estimates are left out (any leg angles, the same answer), and the answer is the one of
    rftgls_core's PosedAnchorSolver on the posed description (the reference path of `rftgls
    capacity --anchor`)."""
    from rftgls_core.description import load_description
    from rftgls_core.geometry.shapes import ellipsoid
    from rftgls_core.geometry.stl import write_stl
    from rftgls_core.posed import PosedAnchorSolver
    from rftgls_core.rft.media import get_medium
    from rftgls_core.types import AnchorState
    write_stl(tmp_path / 'egg.stl', ellipsoid(0.02, 0.015, 0.01, subdivisions=2), units='m')
    (tmp_path / 'egg.urdf').write_text(
        '<robot name="egg"><link name="base_link"><inertial><mass value="0.2"/></inertial>'
        '<collision><geometry><mesh filename="egg.stl"/></geometry></collision></link>'
        '<link name="winch_link"/><joint name="w" type="fixed"><parent link="base_link"/>'
        '<child link="winch_link"/></joint></robot>')
    (tmp_path / 'egg.yaml').write_text(
        'name: egg\nurdf: egg.urdf\nmedium: glass_beads\nsymmetry: sagittal\n'
        'base_pose: {height: depth, pitch: tilt}\nstate:\n'
        '  - {name: depth, unit: m, physical: [-0.2, 0.0]}\n'
        '  - {name: tilt, unit: deg, physical: [-45, 45]}\n')
    p = node_predictor('', 'twist-mesh', medium='glass_beads',
                       anchor_description_file=str(tmp_path / 'egg.yaml'),
                       anchor_state_variables='depth=h,tilt=theta_b')
    a = p.predict(AnchorState(-0.04, math.radians(10), 0.3, -0.2), 0.5, 'backward')
    b = p.predict(AnchorState(-0.04, math.radians(10), -1.0, 1.0), 0.5, 'backward')
    assert a.status.has_value and a.capacity_N == b.capacity_N
    desc = load_description(tmp_path / 'egg.yaml')
    solver = PosedAnchorSolver(get_medium('glass_beads'), method='twist-mesh', space='sagittal')
    ref = solver.solve(desc.pose({'depth': -0.04, 'tilt': math.radians(10)}), 0.5)
    assert a.capacity_N == pytest.approx(ref.capacity_N, rel=TWO_SOLVES_RTOL)  # two solves


@pytest.fixture(scope='module')
def dh_described_map(tmp_path_factory):
    """A small described map of the shipped MiniRQuad description around Table II's DH pose
    (its nodes include DH), twist-mesh, backward pull."""
    from rftgls_core.description import load_description
    from rftgls_core.maps.described import (
        description_grid,
        save_described_map,
    )
    from rftgls_core.maps.described_build import build_described_map
    from rftgls_core.rft.media import get_medium
    desc = load_description(MINIRQUAD)
    grid = description_grid(desc, {'h': [0.034, 0.036], 'theta_b': [5.0, 8.9],
                                   'theta_l1': [-40.0, -20.0], 'theta_l2': [20.0, 30.0]},
                            [-20.0, 0.0], ('backward',))
    data = build_described_map(desc, get_medium('m90_sand'), grid, method='twist-mesh')
    return save_described_map(tmp_path_factory.mktemp('dmap') / 'dh.h5', data)


def test_capacity_node_serves_a_described_map_for_its_description(dh_described_map):
    """map_file = a described map + anchor_description_file = its description: at a node the
    answer is the live description solver's (float32 storage), twist in the sagittal form."""
    from rftgls_core.predictor.maps import DescribedMapPredictor
    p = node_predictor(str(dh_described_map), medium='m90_sand', pull='backward',
                       anchor_description_file=MINIRQUAD)
    assert isinstance(p, DescribedMapPredictor)
    live = node_predictor('', 'twist-mesh', anchor_description_file=MINIRQUAD)
    dh = ANCHOR_MODES['DH']
    for phi in (0.0, math.radians(-20.0)):
        a, b = live.predict(dh, phi, 'backward'), p.predict(dh, phi, 'backward')
        assert a.status == b.status and b.capacity_N is not None
        assert b.capacity_N == pytest.approx(a.capacity_N, rel=1e-6)
        assert b.slip_twist_scaled == pytest.approx(a.slip_twist_scaled, abs=1e-5)
        assert b.slip_twist == pytest.approx(a.slip_twist, abs=1e-5)
    off = p.predict(ANCHOR_MODES['SH'], 0.0, 'backward')        # off the small grid
    assert off.status.value == 'out_of_range' and off.capacity_N is None


@pytest.mark.parametrize('kw, must', [
    ({}, 'set anchor_description_file'),
    ({'anchor_description_file': str(shipped_description('prototype'))},
     'does not answer for anchor_description_file'),
    ({'anchor_description_file': MINIRQUAD, 'medium': 'glass_beads'}, "for medium 'm90_sand'"),
    ({'anchor_description_file': MINIRQUAD, 'pull': 'forward'}, "not 'forward'"),
])
def test_a_described_map_the_node_cannot_use_is_one_line(dh_described_map, kw, must):
    args = {'medium': 'm90_sand', 'pull': 'backward', **kw}
    with pytest.raises(ConfigError) as err:
        node_predictor(str(dh_described_map), **args)
    assert '\n' not in str(err.value) and must in str(err.value), str(err.value)
