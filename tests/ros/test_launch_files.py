"""Every launch file of rftgls_ros, as installed by colcon, is checked without ROS 2's launch
(rftgls_ros.launch_check): executables exist where `ros2 run` looks, each program's own
argument parsing accepts the command line launch_ros builds for it (`--ros-args -r
__node:=... --params-file <temporary YAML> ...`, rules read from launch_ros 0.26, Jazzy), each
parameter is declared by its node and accepted with its type, remappings name topics the node
uses. The checker itself must catch each kind of mistake (a file with one of each), and the
command lines must be launch_ros's."""
from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest
import yaml

pytest.importorskip('rclpy')

from rftgls_ros import launch_check, launch_model  # noqa: E402

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
                                         'replay.launch.py', 'teleop.launch.py'}
    for src in SOURCES:
        assert installed(src.name).read_text() == src.read_text(), src.name
    share = launch_check.share_dir('rftgls_ros')
    for f in ('params/capacity_node.yaml', 'params/behavior_node.yaml',
              'config/capacity.rviz', 'config/capacity.foxglove.json'):
        assert (share / f).is_file(), f
    core = launch_check.share_dir('rftgls_core')
    assert (core / 'maps' / 'minirquad_m90_sand.h5').is_file()
    desc = launch_check.share_dir('minirquad_description')
    for f in ('urdf/minirquad.urdf', 'urdf/prototype.urdf', 'meshes/c_leg.stl'):
        assert (desc / f).is_file(), f


@pytest.mark.parametrize('src', SOURCES, ids=lambda p: p.name)
def test_launch_file_is_sound(src):
    parsed = launch_check.parse(installed(src.name), ARGS.get(src.name))
    assert parsed.nodes, 'no nodes found'
    assert launch_check.check(installed(src.name), ARGS.get(src.name)) == []


def test_sim_launch_starts_the_whole_stack():
    nodes = launch_check.parse(installed('sim.launch.py'), {'sled_mass_kg': '0.6'}).nodes
    exes = [(n.kind, n.package, n.executable) for n in nodes]
    assert exes == [('process', 'minirquad_sim', 'minirquad_sim'),   # not a ROS node
                    ('node', 'minirquad_driver', 'bridge_node'),
                    ('node', 'rftgls_ros', 'capacity_node'),
                    ('node', 'rftgls_ros', 'state_publisher'),
                    ('node', 'rftgls_ros', 'behavior_node')]
    sim, bridge, _cap, tf, behavior = nodes
    # The simulator's pty symlink is the port the bridge opens; the sled mass reaches both.
    port = sim.arguments[sim.arguments.index('--symlink') + 1]
    assert bridge.parameters == [{'port': port}]
    assert sim.arguments[sim.arguments.index('--sled-mass') + 1] == '0.6'
    assert behavior.parameters[1]['sled_mass_kg'] == 0.6
    assert behavior.remappings == [('imu', 'imu/data')]
    desc = launch_check.share_dir('minirquad_description') / 'urdf' / 'minirquad.urdf'
    assert tf.parameters == [{'robot_description': desc.read_text()}]


def test_teleop_launch_starts_the_stack_teleop_needs():
    """`make teleop-sim`: simulator, bridge, capacity_node reading teleop's tether angle, and
    state_publisher; no behavior_node (teleop commands the winch instead)."""
    nodes = launch_check.parse(installed('teleop.launch.py'), {'sled_mass_kg': '0.6'}).nodes
    assert [(n.kind, n.package, n.executable) for n in nodes] == [
        ('process', 'minirquad_sim', 'minirquad_sim'), ('node', 'minirquad_driver', 'bridge_node'),
        ('node', 'rftgls_ros', 'capacity_node'), ('node', 'rftgls_ros', 'state_publisher')]
    sim, bridge, cap, _tf = nodes
    assert bridge.parameters == [{'port': sim.arguments[sim.arguments.index('--symlink') + 1]}]
    assert sim.arguments[sim.arguments.index('--sled-mass') + 1] == '0.6'
    assert cap.parameters[1] == {'phi_topic': '/winch/phi'}


def test_an_integer_sled_mass_arrives_as_a_float(tmp_path):
    """`sled_mass_kg:=1`: launch reads a substituted value as YAML (the integer 1), which
    behavior_node's float parameter refuses; the launch file converts it (ParameterValue)."""
    path = installed('sim.launch.py')
    behavior = launch_check.parse(path, {'sled_mass_kg': '1'}).nodes[-1]
    value = behavior.parameters[1]['sled_mass_kg']
    assert value == 1.0 and isinstance(value, float)
    # The float arrives; a 1 kg sled has no gait map, so the planned burrows (the default)
    # refuse it at start, in their own words, and nothing else is wrong.
    problems = launch_check.check(path, {'sled_mass_kg': '1', 'port': str(tmp_path / 'tty')})
    assert all("no gait map for a 1000 g sled" in p for p in problems), problems
    # Without the conversion the node refuses it, and the checker says so.
    bare = tmp_path / 'bare.launch.py'
    bare.write_text(textwrap.dedent('''
        from launch import LaunchDescription
        from launch.actions import DeclareLaunchArgument
        from launch.substitutions import LaunchConfiguration
        from launch_ros.actions import Node

        def generate_launch_description():
            return LaunchDescription([
                DeclareLaunchArgument('m', default_value='0.4'),
                Node(package='rftgls_ros', executable='behavior_node',
                     parameters=[{'sled_mass_kg': LaunchConfiguration('m')}]),
            ])
    '''))
    assert launch_check.check(bare, {'m': '0.4'}) == []
    problems = launch_check.check(bare, {'m': '1'})
    assert len(problems) == 1 and 'sled_mass_kg' in problems[0] and 'INTEGER' in problems[0]


def test_command_lines_are_launch_ros(tmp_path):
    """launch_ros's Node: executable, arguments, --ros-args, -r __node:=, -r __ns:=, one
    --params-file per entry (a dict as {'/**' or the full name: {ros__parameters: ...}}),
    then -r per remapping. ExecuteProcess: the command as given."""
    params = tmp_path / 'given.yaml'
    params.write_text('/**:\n  ros__parameters: {cycles: 2}\n')
    p = launch_model.Process(source='x', kind='node', package='rftgls_ros',
                             executable='behavior_node', name='behavior_node',
                             parameters=[params, {'sled_mass_kg': 1.0}],
                             remappings=[('imu', 'imu/data')], arguments=['--flag'])
    exe = str(launch_model.executable_path('rftgls_ros', 'behavior_node'))
    cmd = launch_model.argv(p, tmp_path)
    assert cmd[:8] == [exe, '--flag', '--ros-args', '-r', '__node:=behavior_node',
                       '--params-file', str(params), '--params-file']
    assert cmd[9:] == ['-r', 'imu:=imu/data']
    assert yaml.safe_load(Path(cmd[8]).read_text()) == \
        {'/**': {'ros__parameters': {'sled_mass_kg': 1.0}}}
    p.namespace = 'robot1'
    cmd = launch_model.argv(p, tmp_path)
    assert cmd[3:7] == ['-r', '__node:=behavior_node', '-r', '__ns:=/robot1']
    assert list(yaml.safe_load(Path(cmd[10]).read_text())) == ['/robot1/behavior_node']
    sim = launch_model.Process(source='x', kind='process', package='minirquad_sim',
                               executable='minirquad_sim', arguments=['--symlink', 't'])
    assert launch_model.argv(sim, tmp_path)[1:] == ['--symlink', 't']


def test_checker_finds_mistakes(tmp_path):
    bad = tmp_path / 'bad.launch.py'
    bad.write_text(textwrap.dedent('''
        from launch import LaunchDescription
        from launch.actions import ExecuteProcess
        from launch.substitutions import LaunchConfiguration
        from launch_ros.actions import Node
        from launch_ros.substitutions import ExecutableInPackage

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
                ExecuteProcess(cmd=[ExecutableInPackage(executable='minirquad_sim',
                                                        package='minirquad_sim'),
                                    '--no-such-option']),
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
    assert 'minirquad_sim: not an rclpy node class; it takes no parameters' in text
    assert 'refuses its command line' in text and '--no-such-option' in text
    assert "launch argument 'undeclared' has no value" in text
    assert len(problems) == 8, text


def test_the_tug_path_runs_behind_its_prefix(tmp_path):
    """bringup.launch.py: bridge_node, capacity_node and behavior_node behind
    `tug_path_prefix` (default `nice -n -5`) and then launch's `launch-prefix`, split as
    launch's Executable does (shlex) and put in front of the command; state_publisher gets
    `launch-prefix` alone (no prefix of its own: launch's default)."""
    path = installed('bringup.launch.py')
    tug_path = {'bridge_node', 'capacity_node', 'behavior_node'}

    def prefixes(args):
        return {n.executable: n.prefix for n in launch_check.parse(path, args).nodes}
    nice = ['nice', '-n', '-5']
    assert prefixes({}) == {**{n: nice for n in tug_path}, 'state_publisher': []}
    assert prefixes({'tug_path_prefix': ''}) == {n: [] for n in (*tug_path, 'state_publisher')}
    gdb = prefixes({'launch-prefix': "gdb -ex run --args"})
    assert gdb['behavior_node'] == [*nice, 'gdb', '-ex', 'run', '--args']
    assert gdb['state_publisher'] == ['gdb', '-ex', 'run', '--args']
    behavior = launch_check.parse(path).nodes[-1]
    exe = str(launch_model.executable_path('rftgls_ros', 'behavior_node'))
    assert launch_model.argv(behavior, tmp_path)[:4] == [*nice, exe]
    assert launch_model.program_argv(behavior, tmp_path)[0] == exe
    # sim.launch.py passes it on to the file it includes.
    sim = launch_check.parse(installed('sim.launch.py'), {'tug_path_prefix': 'chrt -f 10'})
    assert {n.executable: n.prefix for n in sim.nodes}['capacity_node'] == ['chrt', '-f', '10']
    # The checker finds a prefix program that does not exist.
    problems = launch_check.check(path, {'tug_path_prefix': 'no_such_prefix_program -x'})
    assert len(problems) == 3 and all('no_such_prefix_program' in p for p in problems)


def test_the_checker_builds_its_nodes_deaf_to_the_ros_graph(ros_context):
    """The checker's private context discovers no one (range OFF), so the participant it
    deletes after each check never has a discovery callback in flight (Fast DDS 2.14 can
    spin for good in that deletion: docs/design/jazzy-robot.md, "The teardown timer"). A
    node of a normal context in the same domain and process sees only itself, and the
    checker's node sees only itself; the caller's environment is as before."""
    import time

    import rclpy
    from rclpy.node import Node
    before = dict(os.environ)
    peer = Node('peer_of_the_checker', context=ros_context)
    ctx = launch_check._init(['prog'])
    assert dict(os.environ) == before
    checked = Node('checked_node', context=ctx)
    try:
        time.sleep(1.5)   # discovery on loopback takes tens of ms; 1.5 s leaves no doubt
        assert checked.get_node_names() == ['checked_node']
        assert peer.get_node_names() == ['peer_of_the_checker']
    finally:
        checked.destroy_node()
        peer.destroy_node()
        rclpy.try_shutdown(context=ctx)
