"""capacity_node's live solver and the simulator's true ground on an anchor description
(issue 12, item 2): the shipped descriptions give the numbers of the robot presets, a map
built for another robot is refused, a description the node cannot estimate is refused in one
line. No ROS needed (the predictor and ground are built the way the node and simulator do)."""
from __future__ import annotations

import math

import pytest

from minirquad_driver.sim.ground import LiveGround
from minirquad_driver.sim.main import build_parser
from rftgls_core.cli.demo import ANCHOR_MODES
from rftgls_core.description import shipped_description, write_robot_description
from rftgls_ros.capacity.params import DEFAULTS
from rftgls_ros.capacity.predictor import (
    ConfigError,
    DescriptionPredictor,
    LivePredictor,
    predictor_from_params,
)

MINIRQUAD = str(shipped_description('minirquad'))


@pytest.mark.parametrize('method', ['direct', 'twist-mesh'])
def test_the_shipped_description_gives_the_live_predictor_numbers(method):
    ref = predictor_from_params('', method, 'minirquad', 'm90_sand', 0, 'backward')
    desc = predictor_from_params('', method, 'minirquad', 'm90_sand', 0, 'backward',
                                 anchor_description_file=MINIRQUAD)
    assert isinstance(ref, LivePredictor) and isinstance(desc, DescriptionPredictor)
    for state in ANCHOR_MODES.values():          # Table II: DH, DL, SH
        for pull in ('backward', 'forward'):
            for phi in (0.0, math.radians(-20.0)):
                a, b = ref.predict(state, phi, pull), desc.predict(state, phi, pull)
                assert a.status == b.status
                if a.capacity_N is None:
                    assert b.capacity_N is None
                    continue
                assert b.capacity_N == pytest.approx(a.capacity_N, rel=1e-9, abs=1e-12)
                assert b.slip_twist == pytest.approx(a.slip_twist, abs=1e-9)


def test_the_default_parameter_keeps_the_robot_shortcut():
    assert DEFAULTS['anchor_description_file'] == ''


def test_a_map_for_another_description_is_refused():
    proto = str(shipped_description('prototype'))
    with pytest.raises(ConfigError, match='does not answer for anchor_description_file'):
        predictor_from_params('minirquad', robot='minirquad', medium='m90_sand',
                              anchor_description_file=proto)
    # the robot's own description is accepted with its shipped map
    predictor_from_params('minirquad', robot='minirquad', medium='m90_sand',
                          anchor_description_file=MINIRQUAD)


def test_a_description_the_node_cannot_estimate_is_one_line(tmp_path):
    write_robot_description('minirquad', tmp_path)
    yml = (tmp_path / 'minirquad.yaml').read_text().replace('name: theta_b,', 'name: pitch,')
    (tmp_path / 'renamed.yaml').write_text(yml.replace('pitch: theta_b', 'pitch: pitch'))
    with pytest.raises(ConfigError, match='estimates h, theta_b') as err:
        predictor_from_params('', anchor_description_file=str(tmp_path / 'renamed.yaml'))
    assert '\n' not in str(err.value)
    with pytest.raises(ConfigError, match='anchor_description_file: .*cannot read'):
        predictor_from_params('', anchor_description_file=str(tmp_path / 'missing.yaml'))


def test_the_sim_ground_on_the_shipped_description_is_the_preset_ground():
    args = build_parser().parse_args(['--anchor', MINIRQUAD])
    assert args.anchor == MINIRQUAD
    preset = LiveGround(method='twist-mesh', fallback_method=None)
    described = LiveGround(method='twist-mesh', fallback_method=None, anchor=MINIRQUAD)
    assert 'anchor description' in described.describe()
    for state in ANCHOR_MODES.values():
        for phi in (0.0, math.radians(-20.0)):
            a, b = preset.predict(state, phi), described.predict(state, phi)
            assert a.status == b.status
            if a.capacity is not None:
                assert b.capacity == pytest.approx(a.capacity, rel=1e-9)
                assert b.slip_twist_per_m == pytest.approx(a.slip_twist_per_m, abs=1e-9)
    # the mass scale reaches the described ground too (a heavier robot holds more)
    heavy = LiveGround(method='twist-mesh', fallback_method=None, anchor=MINIRQUAD,
                       mass_scale=1.5)
    dh = ANCHOR_MODES['DH']
    light = described.predict(dh, 0.0).capacity
    assert light is not None and heavy.predict(dh, 0.0).capacity > light


def test_the_warm_live_method_name_gives_the_cold_direct_on_a_description():
    # integ's default live_method is 'direct-warm' (the cold direct's answers, warm-started)
    p = predictor_from_params('', 'direct', anchor_description_file=MINIRQUAD)
    q = DescriptionPredictor(MINIRQUAD, 'm90_sand', 'direct-warm')
    dh = ANCHOR_MODES['DH']
    assert q.model.method == 'direct'
    assert q.predict(dh, 0.0, 'backward').capacity_N == p.predict(dh, 0.0, 'backward').capacity_N
