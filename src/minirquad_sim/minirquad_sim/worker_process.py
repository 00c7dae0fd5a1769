"""A forked worker process on a pipe: what the simulator's background ground and physics share.

The simulated MCU loop must keep its period whatever the sand costs to compute, so the
expensive parts (the live ground's solves, the physics body's steps) run in a worker process.
A process, not a thread: the compiled solvers hold the GIL. The worker is forked, so the
state it serves (a warmed-up solver, a built body, their compiled kernels) comes with it; it
ends when the simulator does (its end of the pipe closes) and ignores SIGINT (a Ctrl-C to the
terminal's process group is the simulator's to handle).
"""
from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from typing import Any


def _run(serve: Callable[[Any, Connection], None], state: Any, conn: Connection,
         parent_end: Connection) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent_end.close()      # the fork's copy: else the pipe never closes when the parent's does
    serve(state, conn)


def start(serve: Callable[[Any, Connection], None], state: Any,
          name: str) -> tuple[Connection, BaseProcess]:
    """Fork a worker running serve(state, its end of the pipe); returns (our end, process).
    serve should return when its end reports EOFError or OSError (the simulator is gone)."""
    ctx = multiprocessing.get_context('fork')
    conn, child = ctx.Pipe()
    proc = ctx.Process(target=_run, args=(serve, state, child, conn), daemon=True, name=name)
    proc.start()
    child.close()
    return conn, proc


def stop(conn: Connection, proc: BaseProcess) -> None:
    """End the worker now (work in progress is not waited for): close the pipe, terminate,
    a timed wait, then kill."""
    conn.close()
    proc.terminate()
    proc.join(1.0)
    if proc.is_alive():
        proc.kill()
        proc.join(1.0)
