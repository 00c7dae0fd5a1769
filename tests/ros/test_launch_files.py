"""Every launch file of rftgls_ros, as installed by colcon, is checked without ROS 2's launch
(rftgls_ros.launch_check): executables exist where `ros2 run` looks, each parameter is declared
by its node and accepted, remappings name topics the node uses. The checker itself must catch
each kind of mistake (a file with one of each)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from rftgls_ros import launch_check  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SOURCES = sorted((REPO / 'src' / 'rftgls_ros' / 'launch').glob('*.launch.py'))
SAMPLE_BAG = REPO / 'src/rftgls_ros/rftgls_ros/lab/samples/forward_L1-040_L2+000'
ARGS = {'replay.launch.py': {'bag': str(SAMPLE_BAG)}}


def installed(name: str) -> Path:
    share = launch_check.share_dir('rftgls_ros')
    assert share is not None, 'rftgls_ros is not on AMENT_PREFIX_PATH (source tools/env.sh)'
    return share / 'launch' / name


def test_every_launch_file_is_installed():
    assert {p.name for p in SOURCES} >= {'bringup.launch.py', 'sim.launch.py',
                                         'replay.launch.py'}
    for src in SOURCES:
        assert installed(src.name).read_text() == src.read_text(), src.name
    share = launch_check.share_dir('rftgls_ros')
    for f in ('params/capacity_node.yaml', 'params/behavior_node.yaml',
              'config/capacity.rviz', 'config/capacity.foxglove.json'):
        assert (share / f).is_file(), f
    core = launch_check.share_dir('rftgls_core')
    assert (core / 'maps' / 'minirquad_m90_sand.h5').is_file()


@pytest.mark.parametrize('src', SOURCES, ids=lambda p: p.name)
def test_launch_file_is_sound(src):
    parsed = launch_check.parse(installed(src.name), ARGS.get(src.name))
    assert parsed.nodes, 'no nodes found'
    assert launch_check.check(installed(src.name), ARGS.get(src.name)) == []


def test_sim_launch_starts_the_whole_stack():
    nodes = launch_check.parse(installed('sim.launch.py'), {'sled_mass_kg': '0.6'}).nodes
    exes = [(n.package, n.executable) for n in nodes]
    assert exes == [('minirquad_sim', 'minirquad_sim'), ('minirquad_driver', 'bridge_node'),
                    ('rftgls_ros', 'capacity_node'), ('rftgls_ros', 'state_publisher'),
                    ('rftgls_ros', 'behavior_node')]
    sim, bridge, _cap, _tf, behavior = nodes
    # The simulator's pty symlink is the port the bridge opens; the sled mass reaches both.
    port = sim.arguments[sim.arguments.index('--symlink') + 1]
    assert bridge.parameters == [{'port': port}]
    assert sim.arguments[sim.arguments.index('--sled-mass') + 1] == '0.6'
    assert behavior.parameters[1]['sled_mass_kg'] == 0.6


def test_checker_finds_mistakes(tmp_path):
    bad = tmp_path / 'bad.launch.py'
    bad.write_text(textwrap.dedent('''
        from launch import LaunchDescription
        from launch.substitutions import LaunchConfiguration
        from launch_ros.actions import Node

        def generate_launch_description():
            return LaunchDescription([
                Node(package='rftgls_ros', executable='no_such_exe'),
                Node(package='rftgls_ros', executable='capacity_node',
                     parameters=['/nonexistent/params.yaml', {'no_such_param': 1.0}],
                     remappings=[('/not_a_topic', '/x'), ('/joint_states', '/robot/js')]),
                Node(package='rftgls_ros', executable='capacity_node', name='cap2',
                     parameters=[{'publish_rate_hz': -1.0}]),
                Node(package='minirquad_sim', executable='minirquad_sim',
                     parameters=[{'port': 'x'}]),
                Node(package='rftgls_ros', executable='behavior_node',
                     parameters=[{'sled_mass_kg': LaunchConfiguration('undeclared')}]),
            ])
    '''))
    problems = launch_check.check(bad)
    text = '\n'.join(problems)
    assert "no executable lib/rftgls_ros/no_such_exe" in text
    assert 'params.yaml does not exist' in text
    assert "parameter 'no_such_param' is not declared" in text
    assert "remapping source '/not_a_topic'" in text
    assert "'/joint_states'" not in text                      # a real input is fine
    assert 'refuses its launch parameters' in text and 'publish_rate_hz' in text
    assert 'minirquad_sim: not an rclpy node' in text
    assert "launch argument 'undeclared' has no value" in text
    assert len(problems) == 7, text
