"""The one `main()` shape of every rclpy executable of the stack (bridge_node, capacity_node,
behavior_node, teleop): `--help`, start-up errors in one line, a spin loop that sees Ctrl-C and
SIGTERM promptly, a best-effort safe stop, and a clean shutdown. Executables without a node
(minirquad_sim, behavior_demo) stop the same way through `stop_on_signals`.

Why spin_once with a timeout and not rclpy.spin: docs/design/ros2-from-pip.md#stopping-nodes.
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from rftgls_conventions import one_line

from .dds_loopback import during_init

HELP_FLAGS = ('-h', '--help')


def user_args(argv: Sequence[str]) -> list[str]:
    """The arguments before `--ros-args` (those are the program's own; the rest are ROS's)."""
    argv = list(argv)
    return argv[:argv.index('--ros-args')] if '--ros-args' in argv else argv


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


def stop_on_signals(event: threading.Event | None = None) -> threading.Event:
    """SIGINT (Ctrl-C) and SIGTERM set `event` (a new one if None) instead of raising, so a
    loop that checks it finishes its iteration and cleans up. Returns the event."""
    event = event or threading.Event()

    def _set(_sig, _frame) -> None:
        event.set()
    signal.signal(signal.SIGINT, _set)
    signal.signal(signal.SIGTERM, _set)
    return event


def wants_help(argv: Sequence[str] | None) -> bool:
    return any(a in HELP_FLAGS for a in user_args(sys.argv[1:] if argv is None else argv))


def run_node(make_node: Callable[[], Any], executable: str, *,
             config_errors: tuple[type[BaseException], ...] = (),
             tick: Callable[[Any], bool] | None = None,
             on_exit: Callable[[Any], None] | None = None,
             spin_period_s: float = 0.1, args: Sequence[str] | None = None) -> int:
    """rclpy.init, build the node, spin until shutdown; returns the exit code.

    make_node: builds the node (after rclpy.init); an exception of `config_errors` (or
        rclpy's ParameterException) is a user error: one line on stderr, exit code 2.
    tick(node): called after every spin_once; return False to stop (e.g. the run is done).
    on_exit(node): the safe stop (winch 0, a report), run once on the way out, even after
        Ctrl-C; its errors are ignored (the context may already be gone).
    """
    import rclpy
    from rclpy.exceptions import ParameterException
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    with during_init():            # DDS on loopback (dds_loopback.py)
        rclpy.init(args=args)
    try:
        node = make_node()
    except (ParameterException, *config_errors) as exc:
        print(f'{executable}: error: {one_line(exc)}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=spin_period_s)
            if tick is not None and not tick(node):
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if on_exit is not None:
            try:
                on_exit(node)
            except Exception:  # noqa: BLE001 - shutting down anyway
                pass
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
