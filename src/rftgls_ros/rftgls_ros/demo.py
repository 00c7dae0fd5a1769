"""``behavior_demo``: the whole stack without ``launch`` (``make demo``).

For each sled mass it starts the simulated MiniRQuad (``minirquad_sim`` on a pseudo-terminal),
``bridge_node``, ``capacity_node``, ``state_publisher`` (TF) and ``behavior_node`` as ``ros2 run``
processes, prints the behaviour's decisions and live predictions, waits for its cycles to
finish, stops every child (SIGINT -> timed wait -> SIGTERM -> kill), and writes the merged
cycle report (CSV + PNG, like the paper's Fig. 12) under ``--out``.

    behavior_demo --out out/demo                         # simulator, 3 cycles x 400 g, 600 g
    behavior_demo --body scripted                        # the simulator's scripted body
    behavior_demo --port /dev/ttyACM0 --sleds 0.4        # a real robot on a serial port

The simulated robot burrows, tugs and slips with the whole-robot RFT physics by default
(``minirquad_sim --body burrow-physics``): the burrowed pose and the burrow energy emerge from
the planned gait and the simulator's own medium, nothing copied from the paper's Table II;
only the walk is scripted (the physics' walk overturns: docs/design/walk-burrow-physics.md).

The tug path (bridge_node, capacity_node, behavior_node: the nodes a winch stop goes through)
runs behind ``--tug-path-prefix``, by default ``nice -n -5``, the priority bringup.launch.py
gives it on the robot (docs/design/stop-budget.md, "Priority of the tug path"); the simulator
and state_publisher run at the demo's own.

DDS stays on loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless set) and the demo uses
its own ROS_DOMAIN_ID when none is set (reserved like ROS 2's domain_coordinator).

Every decision is made on the lower bound: the summary gives, per sled, the mode chosen with its
lower bound (the number the choice was made on), its point estimate, the need and the predicted
and measured burrow energy, and checks the cycle report: no cycle reeled in while capacity_node's
lower bound was below the need.

Exit status: 0 when every sled ran its cycles; 4 when a sled was refused (no mode's lower bound
covers its need: no tug, the reason printed); 3 when a tug was aborted for lack of evidence (a
cycle with outcome ``aborted``) unless ``--allow-aborts``; 5 when a cycle reeled in below the
need (a broken safety rule); 1 when a sled produced no report (behavior_node did not finish);
130 on Ctrl-C.
"""
from __future__ import annotations

import argparse
import math
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from rftgls_conventions.safe_read import check_regular
from rftgls_conventions.safe_write import open_fresh, output_folder
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.quantities import MASS_KG, RUN_TIMEOUT_S, bounded_int
from rftgls_node_base.node_main import program_args, stop_on_signals

from .behavior.report import CycleRecord, read_csv, write_report
from .warm_up import warm_up

_stop = threading.Event()
CAPACITY_PARAMS = Path('ros2_ws/params/capacity_node.yaml')   # the shipped capacity_node file
# bringup.launch.py's tug_path_prefix default: the demo runs the tug path as the robot does
TUG_PATH_PREFIX = 'nice -n -5'


def _reserve_domain() -> tuple[int, socket.socket]:
    """A ROS domain id 1..100 nobody on this host holds (TCP port 32768 + id as the lock)."""
    start = 1 + os.getpid() % 100
    for k in range(100):
        d = 1 + (start + k - 1) % 100
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            s.bind(('127.0.0.1', 32768 + d))
            return d, s
        except OSError:
            s.close()
    raise RuntimeError('no free ROS domain id')


# The stack's programs: executable -> (its package, the module `python -m` runs when there is
# no `ros2` on PATH).
PROGRAMS = {
    'minirquad_sim': ('minirquad_sim', 'minirquad_sim.main'),
    'bridge_node': ('minirquad_driver', 'minirquad_driver.bridge_node'),
    'capacity_node': ('rftgls_ros', 'rftgls_ros.capacity_node'),
    'state_publisher': ('rftgls_ros', 'rftgls_ros.state_publisher'),
    'behavior_node': ('rftgls_ros', 'rftgls_ros.behavior_node'),
}


def command_prefix(text: str) -> list[str]:
    """An argparse `type`: a command to put in front of a node's command line, split as a
    shell would ('' = none); its program must be on PATH."""
    try:
        words = shlex.split(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f'not a command: {text!r} ({exc})') from None
    if words and shutil.which(words[0]) is None:
        raise argparse.ArgumentTypeError(f'{words[0]!r} is not a program on PATH')
    return words


def try_prefix(prefix: list[str]) -> tuple[int, str]:
    """Run `true` behind prefix: its exit status and what it said on stderr. GNU nice without
    the right to raise a priority says "cannot set niceness" and runs the command anyway (0);
    chrt without it runs nothing (1)."""
    if not prefix:
        return 0, ''
    try:
        r = subprocess.run([*prefix, 'true'], capture_output=True, text=True, timeout=10.0)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return 1, str(exc)
    return r.returncode, r.stderr.strip()


def tug_path_line(prefix: list[str], said: str) -> str:
    """The demo's line on the tug path's prefix, with what the prefix said when tried."""
    line = ('behavior_demo: tug path (bridge_node, capacity_node, behavior_node) behind '
            + (shlex.join(prefix) or 'no prefix'))
    if said:
        line += (f" (it says: {said.splitlines()[-1]}; how to give this user the right: "
                 "docs/design/stop-budget.md, 'Priority of the tug path')")
    return line


def _ros2_run(exe: str) -> list[str]:
    pkg, module = PROGRAMS[exe]
    ros2 = shutil.which('ros2')
    return [ros2, 'run', pkg, exe] if ros2 else [sys.executable, '-m', module]


def stop_process(proc: subprocess.Popen, timeout: float = 3.0) -> None:
    """SIGINT -> timed wait -> SIGTERM -> timed wait -> SIGKILL."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            return
        proc.send_signal(sig)
        try:
            proc.wait(timeout)
            return
        except subprocess.TimeoutExpired:
            continue


class Stack:
    """The processes of one run; ``close()`` stops them in reverse order."""

    def __init__(self, env: dict, log_dir: Path):
        self.env = env
        self.log_dir = log_dir
        self.procs: list[tuple[str, subprocess.Popen]] = []
        self._files = []

    def start(self, name: str, argv: list[str], echo: bool = False) -> subprocess.Popen:
        log = open_fresh(self.log_dir / f'{name}.log')    # a planted link is replaced
        self._files.append(log)
        if echo:
            proc = subprocess.Popen(argv, env=self.env, stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True, bufsize=1)
            threading.Thread(target=_tee, args=(proc.stdout, log), daemon=True).start()
        else:
            proc = subprocess.Popen(argv, env=self.env, stdout=log, stderr=subprocess.STDOUT)
        self.procs.append((name, proc))
        return proc

    def close(self) -> None:
        for _name, p in reversed(self.procs):
            stop_process(p)
        for f in self._files:
            f.close()


def _tee(stream, log) -> None:
    for line in stream:
        log.write(line)
        log.flush()
        sys.stdout.write('  ' + line if line.startswith(' ') else line)
        sys.stdout.flush()


def run_set(args, sled: float, env: dict, out: Path, params: Path | None) -> Path | None:
    """One stack, ``args.cycles`` cycles with a ``sled`` kg sled; returns its report CSV."""
    tag = f'sled_{round(1e3 * sled)}g'
    log_dir = out / 'logs' / tag
    log_dir.mkdir(parents=True, exist_ok=True)
    (out / tag / 'cycle_report.csv').unlink(missing_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix='minirquad_'))
    stack = Stack(env, log_dir)
    try:
        port = args.port
        if not port:
            link_file, port = tmp / 'link', str(tmp / 'tty')
            sim = [*_ros2_run('minirquad_sim'), '--link-file',
                   str(link_file), '--symlink', port, '--sled-mass', str(sled),
                   '--body', args.body]
            sim += args.sim_arg or []
            stack.start('minirquad_sim', sim)
            deadline = time.monotonic() + 10.0
            while not link_file.exists() and time.monotonic() < deadline and not _stop.is_set():
                time.sleep(0.05)
            if not link_file.exists():
                print('demo: the simulator did not open its pty', file=sys.stderr)
                return None
        tug_path = args.tug_path_prefix
        stack.start('bridge_node', [*tug_path, *_ros2_run('bridge_node'),
                                    '--ros-args', '-p', f'port:={port}'])
        cap = [*tug_path, *_ros2_run('capacity_node'), '--ros-args']
        if CAPACITY_PARAMS.exists():
            cap += ['--params-file', str(CAPACITY_PARAMS)]
        cap += ['-p', 'phi_topic:=winch/phi']   # relative: behavior_node's winch/phi
        stack.start('capacity_node', cap)
        # /tf and /tf_static for RViz/Foxglove (odom -> base_link -> legs, imu_link, winch_link)
        stack.start('state_publisher', [*_ros2_run('state_publisher'),
                                        '--ros-args', '-p', 'robot:=minirquad'])
        beh = [*tug_path, *_ros2_run('behavior_node'), '--ros-args']
        if params:
            beh += ['--params-file', str(params)]
        beh += ['-p', f'sled_mass_kg:={sled}', '-p', f'cycles:={args.cycles}',
                '-p', f'report_dir:={out / tag}', '-p', 'exit_when_done:=true',
                '-r', 'imu:=imu/data']          # REP-145's topic, as bringup.launch.py
        for kv in args.param or []:
            beh += ['-p', kv]
        print(f'\n=== {1e3 * sled:.0f} g sled: {args.cycles} walk-burrow-tug cycles '
              f'({f"simulated MiniRQuad, {args.body} body" if not args.port else args.port}) ===',
              flush=True)
        proc = stack.start('behavior_node', beh, echo=True)
        deadline = time.monotonic() + args.timeout
        while proc.poll() is None and time.monotonic() < deadline and not _stop.is_set():
            time.sleep(0.1)
        if proc.poll() is None:
            print(f'demo: behavior_node still running after {args.timeout:.0f} s; stopping',
                  flush=True)
    finally:
        stack.close()
        shutil.rmtree(tmp, ignore_errors=True)
    csv_path = out / tag / 'cycle_report.csv'
    return csv_path if csv_path.exists() else None


@cli_contract('behavior_demo')
def main(argv: list[str] | None = None) -> int:
    p = RftglsParser(prog='behavior_demo', description=__doc__.split('\n\n')[0])
    p.add_argument('--out', default='out/demo', help='report folder (default %(default)s)')
    p.add_argument('--sleds', type=MASS_KG.arg, nargs='+', default=[0.4, 0.6], help='kg')
    p.add_argument('--cycles', type=bounded_int(1, 1000, 'cycle count'), default=3)
    p.add_argument('--params', default='ros2_ws/params/behavior_node.yaml',
                   help='behavior_node parameter file (skipped if missing)')
    p.add_argument('--param', action='append', metavar='NAME:=VALUE',
                   help='extra behavior_node parameter (repeatable)')
    p.add_argument('--port', help='serial port of a real MiniRQuad (no simulator)')
    p.add_argument('--body', choices=('burrow-physics', 'scripted'), default='burrow-physics',
                   help="the simulated robot's body (minirquad_sim --body): burrow-physics, the "
                        "whole-robot RFT physics from standing on (burrows, tugs, slips; the "
                        "walk scripted); scripted, burrows ending at the gait map's predicted "
                        "pose (default %(default)s)")
    p.add_argument('--sim-arg', action='append', help='extra minirquad_sim argument')
    p.add_argument('--tug-path-prefix', type=command_prefix, default=TUG_PATH_PREFIX,
                   help='command in front of bridge_node, capacity_node and behavior_node, as '
                        "bringup.launch.py's tug_path_prefix ('' = none; default "
                        '%(default)s)')
    # A sled's three cycles may each burrow up to max_burrows_per_cycle (3) times when the
    # check at the measured pose falls short: 29 s for such a 600 g cycle here, so 75 s cut
    # the third cycle of runs that were going well (demo exit 3, "aborted (shutdown)").
    p.add_argument('--timeout', type=RUN_TIMEOUT_S.arg, default=150.0, help='per sled, s')
    p.add_argument('--allow-aborts', action='store_true',
                   help='exit 0 even if a tug was aborted (fault-injection runs)')
    args = p.parse_args(program_args(argv, p.prog))
    # A prefix that runs nothing would leave the stack unstarted until the timeout.
    code, said = try_prefix(args.tug_path_prefix)
    if code != 0:
        p.error(f'argument --tug-path-prefix: {shlex.join(args.tug_path_prefix)!r} fails here '
                f'(exit {code}){": " + said.splitlines()[-1] if said else ""}')

    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    lock = None
    if not env.get('ROS_DOMAIN_ID'):
        domain, lock = _reserve_domain()
        env['ROS_DOMAIN_ID'] = str(domain)
    env.setdefault('RCUTILS_LOGGING_USE_STDOUT', '1')
    env.setdefault('RCUTILS_CONSOLE_OUTPUT_FORMAT', '[{name}] {message}')
    env.setdefault('MPLBACKEND', 'Agg')
    env['PYTHONUNBUFFERED'] = '1'
    out = output_folder(args.out, '--out')     # a folder, checked before anything starts
    params = None
    if args.params and os.path.lexists(args.params):   # a FIFO would hang behavior_node
        params = check_regular(args.params, 'params', 'parameter file')

    stop_on_signals(_stop)

    t0 = time.monotonic()
    print(f'behavior_demo: ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, DDS discovery '
          f'{env["ROS_AUTOMATIC_DISCOVERY_RANGE"]}, logs in {out / "logs"}', flush=True)
    print(tug_path_line(args.tug_path_prefix, said), flush=True)
    # The nodes' numba kernels, compiled before they are needed mid-tug (warm_up.py).
    print('behavior_demo: preparing the solvers (compiled on first use: slow only on a '
          "machine's first run)", flush=True)
    took = warm_up(CAPACITY_PARAMS if CAPACITY_PARAMS.exists() else None)
    print(f'behavior_demo: solvers ready ({took:.1f} s)', flush=True)
    records = []
    missing = []
    try:
        for sled in args.sleds:
            if _stop.is_set():
                break
            csv_path = run_set(args, sled, env, out, params)
            if csv_path:
                records += read_csv(csv_path)
            else:
                missing.append(sled)
    finally:
        if lock:
            lock.close()
    if not records:
        print('behavior_demo: no cycle completed', file=sys.stderr)
        return 1
    csv_path, png_path = write_report(records, out)
    print(f'\n=== summary ({time.monotonic() - t0:.0f} s) ===')
    # a cycle's modes are its burrows joined by '+' (a planned gait's name alone is 16 wide)
    w = max(8, *(len(r.mode) for r in records))
    print(f'{"sled":>6} {"cycle":>5} {"mode":>{w}} {"outcome":>8} {"walk J":>7} {"burrow J":>8} '
          f'{"tug J":>6} {"dist m":>7}  last stop (resumed, or why the cycle ended)')
    for r in records:
        print(f'{1e3 * r.sled_kg:>4.0f} g {r.cycle:>5} {r.mode:>{w}} {r.outcome:>8} '
              f'{r.walk_j:>7.2f} {r.burrow_j:>8.2f} {r.tug_j:>6.2f} {r.distance_m:>7.3f}  '
              f'{r.reason}')
    for sled in sorted({r.sled_kg for r in records}):
        print(sled_line([r for r in records if r.sled_kg == sled]))
    print(f'cycle report: {csv_path} and {png_path}')
    if _stop.is_set():
        return 130
    aborted = [r for r in records if r.outcome == 'aborted']
    for r in aborted:
        print(f'behavior_demo: {1e3 * r.sled_kg:.0f} g cycle {r.cycle} ABORTED ({r.reason})',
              file=sys.stderr)
    refused = [r for r in records if r.outcome == 'refused']
    for r in refused:
        print(f'behavior_demo: {1e3 * r.sled_kg:.0f} g REFUSED, no tug: {r.decision}',
              file=sys.stderr)
    below = below_need(records)
    for r in below:
        print(f'behavior_demo: {1e3 * r.sled_kg:.0f} g cycle {r.cycle} reeled in '
              f'{-r.reel_lower_margin_n:.2f} N below the need on its lower bound',
              file=sys.stderr)
    if missing:
        print('behavior_demo: no cycle report for '
              + ', '.join(f'{1e3 * m:.0f} g' for m in missing), file=sys.stderr)
        return 1
    if below:
        return 5
    if refused:
        return 4
    if aborted and not args.allow_aborts:
        return 3
    return 0


def sled_line(rows: list[CycleRecord]) -> str:
    """One sled's decision basis, from its cycle report rows: the modes burrowed (or why not)
    with the lower bound the choice was made on and the one the last tug was started on (at
    the measured pose, by CHECK), the point estimate, the need, the burrow energy above idle
    the chooser predicted for the last choice, and the burrow phase's measured energy (idle
    included, mean over the cycles)."""
    sled = f'{1e3 * rows[0].sled_kg:.0f} g sled'
    chosen = [r for r in rows if r.outcome != 'refused' and r.mode != '-']
    if not chosen:
        r = rows[-1]
        return (f'{sled} -> REFUSED: {r.decision} (point estimate {r.point_n:.2f} N; the '
                f'point estimate is never decided on)')
    # every gait burrowed, once, in the order first burrowed (a cycle's mode is 'A+B' when
    # its check sent the robot to burrow again)
    modes = list(dict.fromkeys(g for r in chosen for g in r.mode.split('+')))
    # The last cycle that chose (a retried cycle re-checks the anchor without a new choice).
    last = next((r for r in reversed(chosen) if math.isfinite(r.lower_n)), chosen[-1])
    burrow = sum(r.burrow_j for r in chosen) / len(chosen)
    tugged = (f'{last.check_lower_n:.2f} N at the measured pose (tug started on)'
              if math.isfinite(last.check_lower_n) else 'no tug started')
    return (f'{sled} -> {", ".join(modes)}: lower bound {last.lower_n:.2f} N (chosen on), '
            f'{tugged}, point estimate {last.point_n:.2f} N, need {last.need_n:.2f} N; burrow '
            f'energy {last.energy_pred_j:.2f} J above idle predicted, {burrow:.2f} J measured '
            f'(phase mean, idle included)' + _plan_text(last))


def _plan_text(r: CycleRecord) -> str:
    """A planned gait's predicted pose and probability of holding ('' for a Table II mode)."""
    if not math.isfinite(r.p_hold):
        return ''
    return (f'; planned gait: predicted h {1e3 * r.h_pred_m:.1f} +- '
            f'{1e3 * r.h_pred_sigma_m:.1f} mm, pitch {math.degrees(r.theta_b_pred_rad):.1f} deg,'
            f' holds with p {r.p_hold:.3f}')


def below_need(records: list[CycleRecord]) -> list[CycleRecord]:
    """The cycles that reeled in while capacity_node's lower bound was below the need
    (reel_lower_margin_n < 0; NaN: the winch never reeled in)."""
    return [r for r in records if r.reel_lower_margin_n < 0.0]


if __name__ == '__main__':
    sys.exit(main())
