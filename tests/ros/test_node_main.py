"""The start-up helpers every executable shares (rftgls_node_base.node_main): ROS arguments as
`ros2 run` and launch_ros append them are stripped by rcl's own parser, before and after a
closing `--`; bad ROS arguments are one line and exit 2, like argparse's own errors; a stop
that cannot finish ends by itself, saying where it was stuck."""
from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip('rclpy')

from rftgls_node_base.node_main import (  # noqa: E402
    STOP_GRACE_S,
    program_args,
    user_args,
    wants_help,
)
from rftgls_node_base.teardown_timer import TEARDOWN_S  # noqa: E402


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


GRACE_S = 1.5    # the stop watchdog's grace for the stuck program below (8 s by default)


def node_program(safe_stop: str, grace: str) -> str:
    """A node program that prints 'up' once spinning; its safe stop runs `safe_stop`."""
    return NODE_PROGRAM.replace('@SAFE_STOP@', safe_stop).replace('@GRACE@', grace)


NODE_PROGRAM = '''
import sys, threading
from rclpy.node import Node
from rftgls_node_base.node_main import STOP_GRACE_S, run_node

def make():
    node = Node('stuck_node')
    node.create_timer(0.05, lambda: print('up', flush=True))
    return node

def never_returns(node):
    @SAFE_STOP@

run_node(make, 'stuck_node', on_exit=never_returns, args=None, stop_grace_s=@GRACE@)
'''


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_stop_that_cannot_finish_ends_with_every_stack_and_exit_1(tmp_path, spawn, sig):
    """The stop watchdog (node_main.stop_watchdog): a node program whose stop blocks ends
    its grace after the signal by itself, exit code 1, with the stuck frame on stderr,
    instead of lingering until launch escalates to SIGTERM and SIGKILL."""
    script = tmp_path / 'stuck_node.py'
    # as a callback stuck in native code or a teardown that blocks would
    script.write_text(node_program('threading.Event().wait()', str(GRACE_S)))
    err = tmp_path / 'stderr.txt'
    proc = spawn([sys.executable, str(script)], stdout=subprocess.PIPE,
                 stderr=open(err, 'w'), text=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == 'up', err.read_text()
    t0 = time.monotonic()
    proc.send_signal(sig)
    code = proc.wait(timeout=GRACE_S + 10.0)
    took = time.monotonic() - t0
    text = err.read_text()
    assert code == 1, text
    # not before the grace (the stop may take that long), and well before launch's SIGKILL
    # (SIGINT + 5 s SIGTERM + 5 s); the upper margin is scheduling slack on a loaded machine
    assert GRACE_S - 0.1 <= took <= GRACE_S + 5.0, (took, text)
    assert 'never_returns' in text and 'Timeout' in text, text


def run_until_up(spawn, script, env: dict | None = None) -> subprocess.Popen:
    """The program started as a node program is (stdout and stderr piped), once it says up."""
    proc = spawn([sys.executable, str(script)], stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == 'up'
    return proc


def interrupt(proc: subprocess.Popen) -> tuple[str, str, float]:
    """SIGINT, then (the rest of stdout, stderr, s from the signal to the exit)."""
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=STOP_GRACE_S + 10.0)
    return out, err, time.monotonic() - t0


def test_a_clean_stop_is_not_cut_short(tmp_path, spawn):
    """The same node program with a safe stop that returns exits 0 at once: the watchdog
    only ends a stop that overruns."""
    script = tmp_path / 'quick_node.py'
    script.write_text(node_program('pass', 'STOP_GRACE_S'))
    proc = run_until_up(spawn, script)
    _, err, took = interrupt(proc)
    assert proc.returncode == 0, err
    assert took < STOP_GRACE_S, err
    assert 'Timeout' not in err
    assert 'ROS teardown' not in err          # nor the teardown timer (below)


WAITING_PROGRAM = '''
import time
from rclpy.node import Node
from rftgls_node_base.node_main import run_node, stop_requested

def make():
    node = Node('waiting_node')
    def wait_in_a_callback():
        print('up', flush=True)
        t_end = time.monotonic() + 30.0      # a question with a long timeout
        while time.monotonic() < t_end and not stop_requested():
            time.sleep(0.01)
        print('stop seen' if stop_requested() else 'timed out', flush=True)
    node.create_timer(0.05, wait_in_a_callback)
    return node

run_node(make, 'waiting_node', args=None)
'''


def test_a_callback_that_waits_sees_the_stop_request(tmp_path, spawn):
    """node_main.stop_requested: a callback that waits (as behavior_node's capacity
    questions do) sees the SIGINT while the spin loop cannot (it is inside the callback), so
    the node stops within the tested 2 s, exit 0, instead of after the wait's 30 s."""
    script = tmp_path / 'waiting_node.py'
    script.write_text(WAITING_PROGRAM)
    proc = run_until_up(spawn, script)
    out, err, took = interrupt(proc)
    assert proc.returncode == 0, err
    assert out.split() == ['stop', 'seen'], (out, err)
    assert took < 2.0, err


STUCK_TEARDOWN_PROGRAM = '''
import ctypes
from rclpy.node import Node
from rftgls_node_base.node_main import run_node

class StuckNode(Node):
    def destroy_node(self):
        # as rcl_node_fini spinning in Fast DDS's participant deletion: native code that
        # holds the GIL (PyDLL keeps it), where no Python thread or handler can run
        ctypes.PyDLL(None).sleep(30)

def make():
    node = StuckNode('stuck_teardown_node')
    node.create_timer(0.05, lambda: print('up', flush=True))
    return node

def safe_stop(node):
    print('safe stop done', flush=True)
    ctypes.CDLL(None).printf(b'in C stdio\\n')   # buffered: stdout is a pipe

run_node(make, 'stuck_teardown_node', on_exit=safe_stop, args=None)
'''


def test_a_teardown_stuck_in_native_code_ends_at_the_teardown_timer_with_exit_0(
        tmp_path, spawn):
    """node_main arms teardown_timer before the ROS teardown of an exiting program: a
    teardown stuck in native code with the GIL held (as Fast DDS's participant deletion can
    spin, docs/design/jazzy-robot.md) ends TEARDOWN_S after the safe stop, exit 0 with one
    line saying so, inside the 2 s a stop is tested to take; not at the stop watchdog's 8 s
    with exit 1. Without the timer this program runs into the watchdog."""
    script = tmp_path / 'stuck_teardown_node.py'
    script.write_text(STUCK_TEARDOWN_PROGRAM)
    # C stdio buffered as a launched node's is (PYTHONUNBUFFERED would unbuffer it)
    proc = run_until_up(spawn, script, env={'PYTHONUNBUFFERED': ''})
    out, err, took = interrupt(proc)
    assert proc.returncode == 0, err
    assert 'safe stop done' in out, (out, err)
    assert 'in C stdio' in out, (out, err)             # flushed before the exit
    assert 'the ROS teardown did not end within 1 s' in err, err
    assert 'Timeout' not in err, err                    # the watchdog did not fire
    # not before the timer; the upper bound is the stop budget of the launch tests
    assert TEARDOWN_S <= took < 2.0, (took, err)
