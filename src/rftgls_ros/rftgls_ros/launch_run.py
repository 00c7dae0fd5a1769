"""Run a ROS 2 Python launch file without ROS 2's `launch`: the project's stand-in for
`ros2 launch` on machines with ROS from pip wheels.

    python -m rftgls_ros.launch_run FILE.launch.py [name:=value ...] [--for SECONDS]
        [--log-dir DIR]

Every program of the file is started with the command line launch_ros would give it
(rftgls_ros.launch_model: `--ros-args -r __node:=... --params-file <temporary YAML> ...`), in
the caller's environment, each one's output in DIR/<name>.log. It runs until Ctrl-C (or
SIGTERM, or --for SECONDS), or until a program exits, then stops the rest the way launch does
at shutdown: SIGINT to every process at once, SIGTERM to those still running after 5 s,
SIGKILL after 5 s more. Exit status 0 when every program ran until the shutdown and exited
0; 1 otherwise (each early exit or failure is one line); 2 when the file does not evaluate.
"""
from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from rftgls_node_base.node_main import program_args, stop_on_signals

from .launch_model import Process, argv, parse


@dataclass
class Running:
    """One started program: its name (executable, numbered when repeated), the Process it
    came from, its command line, its Popen and its log file."""

    name: str
    process: Process
    argv: list[str]
    popen: subprocess.Popen
    log: Path


class Launch:
    """The programs of one launch file. start(), then exited() while it runs, shutdown()."""

    def __init__(self, path: str | Path, args: dict[str, str] | None = None,
                 log_dir: str | Path | None = None, env: dict[str, str] | None = None):
        parsed = parse(path, args)
        if parsed.problems:
            raise ValueError('; '.join(parsed.problems))
        self.processes = parsed.nodes
        self._tmp = tempfile.TemporaryDirectory(prefix='launch_params_')   # as launch_ros's
        self.log_dir = Path(log_dir or tempfile.mkdtemp(prefix='launch_logs_'))
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = env
        self.running: list[Running] = []

    def start(self) -> list[Running]:
        names: dict[str, int] = {}
        for p in self.processes:
            k = names[p.executable] = names.get(p.executable, 0) + 1
            name = p.executable if k == 1 else f'{p.executable}_{k}'
            cmd = argv(p, self._tmp.name)
            log = self.log_dir / f'{name}.log'
            with open(log, 'w') as f:
                popen = subprocess.Popen(cmd, env=self.env, stdout=f, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL)
            self.running.append(Running(name, p, cmd, popen, log))
        return self.running

    def exited(self) -> list[tuple[str, int]]:
        """(name, exit code) of the programs that have stopped."""
        return [(r.name, r.popen.returncode) for r in self.running
                if r.popen.poll() is not None]

    def shutdown(self, sigint_timeout: float = 5.0,
                 sigterm_timeout: float = 5.0) -> dict[str, tuple[int, float]]:
        """Stop every program as launch does; name -> (exit code, s from the SIGINT)."""
        t0 = time.monotonic()
        done: dict[str, tuple[int, float]] = {}
        live = [r for r in self.running if r.popen.poll() is None]
        for r in self.running:
            if r not in live:
                done[r.name] = (r.popen.returncode, 0.0)

        def wait(r: Running, until: float) -> None:
            try:
                r.popen.wait(max(0.0, until - time.monotonic()))
                done[r.name] = (r.popen.returncode, time.monotonic() - t0)
            except subprocess.TimeoutExpired:
                pass
        for sig, timeout in ((signal.SIGINT, sigint_timeout), (signal.SIGTERM, sigterm_timeout),
                             (signal.SIGKILL, 5.0)):
            live = [r for r in live if r.popen.poll() is None and r.name not in done]
            if not live:
                break
            for r in live:
                r.popen.send_signal(sig)
            until = time.monotonic() + timeout
            waiters = [threading.Thread(target=wait, args=(r, until)) for r in live]
            for w in waiters:
                w.start()
            for w in waiters:
                w.join()
        self._tmp.cleanup()
        return done


def main(argv_: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog='launch_run', description=__doc__.split('\n\n')[0])
    ap.add_argument('file')
    ap.add_argument('args', nargs='*', metavar='name:=value')
    ap.add_argument('--for', dest='seconds', type=float, default=0.0,
                    help='stop after this many s (0: until Ctrl-C)')
    ap.add_argument('--log-dir', help='folder of the programs\' logs (default: a temporary one)')
    a = ap.parse_args(program_args(argv_, ap.prog))
    try:
        args = dict(x.split(':=', 1) for x in a.args)
        launch = Launch(a.file, args, a.log_dir)
    except ValueError as exc:
        print(f'launch_run: error: {exc}', file=sys.stderr)
        return 2
    stop = stop_on_signals()
    for r in launch.start():
        print(f'[{r.name}] pid {r.popen.pid}: {" ".join(r.argv)}', flush=True)
    end = time.monotonic() + a.seconds if a.seconds > 0 else float('inf')
    while not stop.is_set() and time.monotonic() < end and not launch.exited():
        time.sleep(0.1)
    early = launch.exited()
    result = launch.shutdown()
    bad = [f'{n} exited early with {code}' for n, code in early]
    bad += [f'{n} exited {code} {t:.1f} s after SIGINT' for n, (code, t) in result.items()
            if code != 0 and n not in dict(early)]
    for line in bad:
        print(f'launch_run: {line}', file=sys.stderr)
    print('launch_run: stopped ' + ', '.join(f'{n} (exit {code}, {t:.2f} s)'
                                             for n, (code, t) in result.items()))
    print(f'launch_run: logs in {launch.log_dir}')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
