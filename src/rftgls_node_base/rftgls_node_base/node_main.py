"""The one `main()` shape of every rclpy executable of the stack (bridge_node, capacity_node,
behavior_node, teleop, state_publisher): `--help`, start-up errors in one line, a spin loop that
sees Ctrl-C and SIGTERM promptly, a safe stop while ROS still works, and a clean shutdown.
Executables without a node (minirquad_sim, behavior_demo) stop the same way through
`stop_on_signals`, and take their own arguments through `program_args`, which strips the ROS
arguments that `ros2 run` and launch_ros's Node action append (`--ros-args ... [--]`).

Signals: rclpy's own SIGINT/SIGTERM handler shuts the context down from the signal, while the
executor may be building a wait set and another thread (the bridge's serial reader) may be
publishing: both then fail with "context is not valid". So rclpy installs no handler here;
the signal only sets an event, the spin loop ends at its next turn, the node's safe stop runs
(the winch commanded to 0 while the link still works), the node is destroyed (its threads
joined) and only then the context is shut down. Why spin_once with a timeout and not
rclpy.spin: docs/design/ros2-from-pip.md#stopping-nodes.

A program that cannot finish stopping (a callback still computing, a teardown that blocks)
does not wait for launch's SIGTERM and SIGKILL: from the first signal (or the end of its spin
loop) it has STOP_GRACE_S to end, after which the interpreter's fault handler writes every
thread's stack to stderr and ends the process with exit code 1 (`stop_watchdog`): an unclean
stop that says where it was stuck. docs/design/jazzy-robot.md, "Stopping on SIGINT". Once
the safe stop is done, the ROS teardown itself has TEARDOWN_S (teardown_timer.py): Fast DDS
can spin for good deleting the participant, after everything the robot needs is done.
"""
from __future__ import annotations

import ctypes
import faulthandler
import os
import signal
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NoReturn

from rftgls_conventions import one_line

from .dds_loopback import during_init
from .teardown_timer import arm_teardown_timer

HELP_FLAGS = ('-h', '--help')
# s from the stop request to the end of the process before the stop watchdog ends it. launch
# sends SIGTERM 5 s after SIGINT (sigterm_timeout; a node here takes it as one more stop
# request) and SIGKILL 5 s later (sigkill_timeout): 8 s writes the stacks before the SIGKILL
# that would end the process silently, and leaves a slow safe stop (behavior_node's report
# and plot on a loaded machine) four times the 2 s a stop is tested to take.
STOP_GRACE_S = 8.0
# The running node's stop request: set by SIGINT/SIGTERM, cleared when run_node starts.
_STOP = threading.Event()


def stop_requested() -> bool:
    """Whether the node run_node is running has been asked to stop (SIGINT or SIGTERM).
    The spin loop sees a stop only between callbacks: a callback that waits (a service call
    with a timeout) polls this to give up at once instead of running its wait out."""
    return _STOP.is_set()


def user_args(argv: Sequence[str]) -> list[str]:
    """argv without its ROS arguments, by rcl's own parser (rclpy.utilities.remove_ros_args):
    everything from `--ros-args` up to a closing `--` (or the end) is ROS's, the rest, before
    and after, the program's. ValueError (one line) on ROS arguments rcl refuses (a params
    file that does not exist or parse, a malformed remap)."""
    argv = list(argv)
    if '--ros-args' not in argv:
        return argv
    from rclpy.utilities import remove_ros_args
    try:
        return list(remove_ros_args(argv))
    except Exception as exc:  # noqa: BLE001 - rclpy raises its own RCLInvalidROSArgsError
        raise ValueError(f'invalid ROS arguments: {one_line(exc)}') from None


def program_args(argv: Sequence[str] | None, prog: str) -> list[str]:
    """The program's own arguments for argparse: argv (default sys.argv[1:]) without the ROS
    arguments `ros2 run` or launch_ros append. Invalid ROS arguments: one line on stderr and
    SystemExit(2), as argparse does for its own."""
    try:
        return user_args(sys.argv[1:] if argv is None else argv)
    except ValueError as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        raise SystemExit(2) from None


def usage(executable: str, package: str, doc: str | None,
          parameters: Mapping[str, Any] | None = None) -> str:
    """Usage text: the first paragraph of the module doc, how to run it, its parameters."""
    lines = [f'usage: ros2 run {package} {executable} [--ros-args -p NAME:=VALUE ...] '
             f'[-r FROM:=TO ...]', '']
    first = (doc or '').strip().split('\n\n')[0]
    if first:
        lines += [first, '']
    if parameters:
        lines.append('parameters (name, default):')
        for name, default in parameters.items():
            lines.append(f'  {name:<30} {default!r}')
    return '\n'.join(lines)


def stop_on_signals(event: threading.Event | None = None,
                    on_stop: Callable[[], None] | None = None) -> threading.Event:
    """SIGINT (Ctrl-C) and SIGTERM set `event` (a new one if None) instead of raising, so a
    loop that checks it finishes its iteration and cleans up; on_stop() runs at each signal
    (e.g. a stop_watchdog's arm). Returns the event."""
    event = event or threading.Event()

    def _set(_sig, _frame) -> None:
        event.set()
        if on_stop is not None:
            on_stop()
    signal.signal(signal.SIGINT, _set)
    signal.signal(signal.SIGTERM, _set)
    return event


def stop_watchdog(grace_s: float = STOP_GRACE_S) -> Callable[[], None]:
    """A function that arms, once, the fault handler's timer: grace_s later every thread's
    stack goes to stderr and the process ends with exit code 1, unless it has ended by then.
    The timer is a C thread: it fires even when the main thread is stuck in native code, where
    no Python signal handler can run. Only for a process that is about to end (`finish`)."""
    armed = False

    def arm() -> None:
        nonlocal armed
        if not armed:           # arming again would restart the timer
            armed = True
            faulthandler.dump_traceback_later(grace_s, exit=True)
    return arm


def wants_help(argv: Sequence[str] | None) -> bool:
    try:
        own = user_args(sys.argv[1:] if argv is None else argv)
    except ValueError:
        return False          # rclpy.init reports the bad ROS arguments
    return any(a in HELP_FLAGS for a in own)


def finish(code: int) -> NoReturn:
    """End the process now with `code`, after flushing Python's and C's stdio buffers (rcutils
    logs through C stdio). Called once the node is destroyed and the context shut down: what
    is left is the interpreter's teardown of native libraries (numba's thread pool, Fast DDS's
    static objects), measured at 0.4-1.4 s per node on 2 idle cores, which alone would spend
    most of the 2 s a launch shutdown should take."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass
    os._exit(code)


def run_node(make_node: Callable[[], Any], executable: str, *,
             config_errors: tuple[type[BaseException], ...] = (),
             tick: Callable[[Any], bool] | None = None,
             on_exit: Callable[[Any], None] | None = None,
             spin_period_s: float = 0.1, args: Sequence[str] | None = None,
             exit_process: bool | None = None, stop_grace_s: float = STOP_GRACE_S) -> int:
    """rclpy.init, build the node, spin until shutdown; returns the exit code.

    make_node: builds the node (after rclpy.init); an exception of `config_errors` (or
        rclpy's ParameterException) is a user error: one line on stderr, exit code 2.
    tick(node): called after every spin_once; return False to stop (e.g. the run is done).
    on_exit(node): the safe stop (winch 0, a report), run once on the way out, even after
        Ctrl-C, while ROS still works; an error there is one line on stderr.
    exit_process: end the process with the code right after the clean shutdown (`finish`)
        instead of returning it; default: when running as the program (args is None).
    stop_grace_s: s from the first SIGINT/SIGTERM (or the end of the spin loop) that such a
        process has to end before the stop watchdog writes every thread's stack to stderr and
        ends it with exit code 1 (stop_watchdog).
    """
    exiting = exit_process if exit_process is not None else args is None
    # Only a process about to end may be ended by the watchdog (not a test calling main(args)).
    arm = stop_watchdog(stop_grace_s) if exiting else None
    # ... and only such a process has its ROS teardown bounded (teardown_timer.py).
    bound_teardown = (lambda: arm_teardown_timer(executable)) if exiting else None
    code = _run_node(make_node, executable, config_errors, tick, on_exit, spin_period_s, args,
                     arm, bound_teardown)
    if exiting:
        release_ros()
        finish(code)
    return code


def release_ros() -> None:
    """Finalise rclpy's default context (after its nodes are destroyed and it is shut down):
    this deletes the process's DDS participant, which tells its peers at once that the nodes
    are gone. `finish` skips the interpreter's teardown that would otherwise do it; without
    this the nodes would linger in every other process's graph until the DDS lease ran out."""
    import gc

    import rclpy
    gc.collect()        # nodes are reference cycles: their handles go with them, then the
    rclpy.get_default_context().destroy()   # context can go (it waits for its last user)


def _run_node(make_node, executable, config_errors, tick, on_exit, spin_period_s,
              args, arm: Callable[[], None] | None,
              bound_teardown: Callable[[], bool] | None) -> int:
    import rclpy
    from rclpy.exceptions import ParameterException
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    _STOP.clear()
    stop = stop_on_signals(_STOP, on_stop=arm)  # before init: no signal meets a half-built node
    try:
        with during_init():        # DDS on loopback (dds_loopback.py)
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: BLE001 - rcl refuses the ROS arguments
        print(f'{executable}: error: {one_line(exc)}', file=sys.stderr)
        return 2
    try:
        node = make_node()
    except (ParameterException, *config_errors) as exc:
        print(f'{executable}: error: {one_line(exc)}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=spin_period_s)
            if tick is not None and not tick(node):
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if arm is not None:
            arm()                  # the stop has begun, whatever ended the loop
        # The safe stop first, while the context and the node's publishers still work.
        if on_exit is not None:
            try:
                on_exit(node)
            except Exception as exc:  # noqa: BLE001 - shutting down anyway, but say so
                print(f'{executable}: safe stop failed: {one_line(exc)}', file=sys.stderr)
        if bound_teardown is not None:
            bound_teardown()
        executor.remove_node(node)
        node.destroy_node()        # joins the node's own threads before the context goes
        executor.shutdown(timeout_sec=0.5)
        rclpy.try_shutdown()
    return 0
