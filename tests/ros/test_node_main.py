"""The start-up helpers every executable shares (rftgls_node_base.node_main): ROS arguments as
`ros2 run` and launch_ros append them are stripped by rcl's own parser, before and after a
closing `--`; bad ROS arguments are one line and exit 2, like argparse's own errors."""
from __future__ import annotations

import pytest

pytest.importorskip('rclpy')

from rftgls_node_base.node_main import program_args, user_args, wants_help  # noqa: E402


def test_launch_ros_argv_is_stripped(tmp_path):
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n    x: 1.0\n')
    argv = ['--symlink', '/tmp/tty', '--ros-args', '-r', '__node:=sim', '-r', '__ns:=/robot',
            '--params-file', str(params), '-r', 'imu:=imu/data']
    assert user_args(argv) == ['--symlink', '/tmp/tty']
    # `--` closes the ROS arguments; what follows is the program's again.
    assert user_args(['a', '--ros-args', '-p', 'x:=1', '--', '--rate', '2']) == \
        ['a', '--rate', '2']
    assert user_args(['a', '--ros-args']) == ['a']          # launch's bare trailing flag
    assert user_args(['a', 'b']) == ['a', 'b']


def test_bad_ros_arguments_are_one_line_and_exit_2(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        program_args(['x', '--ros-args', '--params-file', str(tmp_path / 'missing.yaml')],
                     'prog')
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith('prog: error: invalid ROS arguments') and '\n' not in err


def test_help_is_seen_only_among_the_programs_own_arguments():
    assert wants_help(['--help', '--ros-args', '-r', '__node:=x'])
    assert not wants_help(['--ros-args', '-r', '__node:=x'])
