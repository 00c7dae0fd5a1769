"""``minirquad_sim``: a simulated MiniRQuad microcontroller on a pseudo-terminal.

    minirquad_sim --link-file /tmp/mcu.path --symlink /tmp/minirquad_tty [faults...]
    minirquad_sim --mcu firmware ...      # the compiled firmware instead of the Python MCU

prints the slave path it opened (first line on stdout, then flushes) and speaks the protocol
of src/minirquad_driver/PROTOCOL.md on it until SIGINT/SIGTERM. Fault options: ``--help``.
ROS arguments (`--ros-args ...`, as `ros2 run` and launch_ros append them) are ignored.

On SIGINT/SIGTERM it keeps serving the link for ``--linger`` seconds (0.5 s) before it closes
the pty: a launch file stops every process at once, and a real MCU outlives its host, so the
bridge's last commands (the winch to 0) still land and are acted on.
"""
from __future__ import annotations

import argparse
import json
import select
import sys
import time
from collections import deque

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import encode_frame
from rftgls_conventions.safe_write import open_fresh
from rftgls_node_base.node_main import finish, program_args, stop_on_signals

from .faults import LIVE_FIELDS, FaultConfig, FaultControl, FaultInjector
from .firmware_link import FirmwareLinkError
from .firmware_mcu import FirmwareMcu
from .gait_pose import GaitPoses
from .ground import make_ground
from .ground_worker import BackgroundGround
from .mcu import McuConfig, SimMcu
from .physics import PhysicsBody
from .physics_worker import BackgroundPhysics
from .plant import MotorWinch, PlantRobot
from .pty_link import LinkPathError, PtyLink
from .robot import SimRobot
from .winch import WinchSled

# A loop turn longer than this is reported: the MCU advances at most 0.1 s per turn
# (mcu.SimMcu.tick), so beyond it the plant also loses simulated time.
LATE_TICK_S = 0.1
# The physics body running this far behind the wall clock (physics_worker.py) is reported,
# and again at each further step of it: its telemetry describes a body that far in the past.
BEHIND_REPORT_S = 1.0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='minirquad_sim', description=__doc__.split('\n\n')[0])
    p.add_argument('--mcu', choices=('python', 'firmware'), default='python',
                   help='python: the reference MCU in this process (default); firmware: the '
                        'compiled C++ firmware (fw_sitl, built by `make setup`) runs the '
                        'protocol and the control, this process the physics')
    p.add_argument('--firmware', metavar='PATH',
                   help='fw_sitl binary for --mcu firmware (default: the one make setup built)')
    p.add_argument('--link-file', help='write the slave pty path to this file')
    p.add_argument('--symlink', help='keep this symlink pointing at the current slave pty')
    p.add_argument('--telemetry-hz', type=int, default=100)
    p.add_argument('--power-hz', type=int, default=50)
    p.add_argument('--watchdog', type=float, default=0.5, help='host watchdog timeout, s')
    p.add_argument('--winch-deadman', type=float, default=0.08,
                   help='winch deadman, s (0: off, to test the host watchdog alone)')
    p.add_argument('--clock-start-ms', type=lambda s: int(s, 0), default=0,
                   help='initial MCU clock (e.g. 0xFFFFF000 to cross the uint32 wrap)')
    p.add_argument('--sled-mass', type=float, default=0.400, help='kg')
    p.add_argument('--pace-baud', type=int, default=0,
                   help='emulate a UART: write at most baud/10 bytes per second (0: off)')
    p.add_argument('--record', help='write one JSON line per telemetry frame built (a new '
                   'file)')
    p.add_argument('--command-log', help='write one JSON line per host command handled '
                   '(the Python MCU; a new file)')
    p.add_argument('--linger', type=float, default=0.5,
                   help='s the link keeps being served after SIGINT/SIGTERM')
    p.add_argument('--duration', type=float, default=0.0, help='exit after this many s')
    t = p.add_argument_group('true ground (what the sand really holds; the stack never sees it)')
    t.add_argument('--body', choices=('physics', 'burrow-physics', 'scripted'),
                   default='scripted',
                   help='scripted: the body scripted to Table II\'s poses, the anchor from '
                        '--ground (default); physics: the legs, body and sand of rftgls_core\'s '
                        'whole-robot simulation on the true robot and medium below (its walk '
                        'overturns the robot and runs slower than real time on this machine: '
                        'docs/design/walk-burrow-physics.md); burrow-physics: the walk '
                        'scripted, everything else (standing, burrows, tugs, slips) physics '
                        '(what make demo runs). The physics steps in a worker process')
    t.add_argument('--ground', choices=('live', 'map', 'table'), default='live',
                   help='live: rftgls_core solver (default); map: the shipped map the stack '
                        'predicts with; table: placeholder')
    t.add_argument('--true-robot', default='minirquad', help='robot preset of the live ground')
    t.add_argument('--anchor', default='', metavar='FILE.yaml',
                   help='anchor description of the live ground instead of --true-robot '
                        '(state variables h, theta_b, theta_l1, theta_l2)')
    t.add_argument('--true-medium', default='m90_sand',
                   help='medium preset or medium JSON file of the live ground')
    t.add_argument('--true-medium-scale', type=float, default=1.0,
                   help='multiplies the true medium stress scale (0.7 = 30%% weaker sand)')
    t.add_argument('--true-mass-scale', type=float, default=1.0,
                   help='multiplies the true robot mass seen by the live ground')
    t.add_argument('--ground-solver', choices=('worker', 'inline'), default='worker',
                   help='worker: the live ground solves a new pose in a process of its own and '
                        'answers with its last answer meanwhile, so the MCU loop keeps its '
                        'period (default); inline: the MCU loop waits for each solve')
    g = p.add_argument_group('fault injection')
    g.add_argument('--garbage-rate', type=float, default=0.0)
    g.add_argument('--drop-rate', type=float, default=0.0)
    g.add_argument('--corrupt-rate', type=float, default=0.0)
    g.add_argument('--latency-ms', type=float, default=0.0)
    g.add_argument('--jitter-ms', type=float, default=0.0)
    g.add_argument('--disconnect-at', type=float, help='unplug at this time, s')
    g.add_argument('--disconnect-for', type=float, default=1.0, help='s')
    g.add_argument('--reset-at', type=float, help='MCU reset at this time, s')
    g.add_argument('--seed', type=int, default=1)
    g.add_argument('--fault-control', metavar='FILE.json',
                   help='switch the per-frame faults while running: a JSON object of '
                        'garbage_rate, drop_rate, corrupt_rate, latency_ms, jitter_ms, read '
                        'whenever the file changes (each switch printed as FAULTS {...} AT '
                        '<host wall time s>)')
    return p


def wall_time(mono: float) -> float:
    """The host wall time (time.time, the clock ROS stamps with) of the time.monotonic
    instant `mono`, s. Read afresh each time: the wall clock may be slewed against the
    monotonic one while the simulator runs (chrony slews up to 83 ms/s; this CI machine was
    seen at 5 ms/s), and an offset taken at start would drift from every other process's
    stamps by that much per second."""
    return time.time() - (time.monotonic() - mono)


class _Recorder:
    """JSON lines of what each telemetry frame carried, in wire integers, plus its fate."""

    def __init__(self, path: str | None):
        # A new file (safe_write.open_fresh): a planted link is replaced, never written through.
        self.file = open_fresh(path, 'a', buffering=1) if path else None

    def telemetry(self, seq: int, t_ms: int, tel: m.Telemetry, fault: str | None,
                  host_s: float | None = None) -> None:
        if not self.file:
            return
        self.file.write(json.dumps({
            'seq': seq, 't_ms': t_ms, 'fault': fault,
            'host_s': host_s,     # host wall time of the sample instant: tests' truth
            'legs': [round(a * m.MICRORAD) for a in tel.leg_angles],
            'pitch': round(tel.pitch * m.MICRORAD),
            'tension': round(tel.tension * m.MILLINEWTON),
            'vel': [round(v * m.MILLIRAD_S) for v in tel.leg_velocities],
            'spool': round(tel.spool_position * m.MICROMETRE),
            'spool_v': round(tel.spool_velocity * m.MICROMETRE_S),
            'mode': int(tel.mode), 'flags': int(tel.flags)}) + '\n')

    def close(self) -> None:
        if self.file:
            self.file.close()


class _CommandLog:
    """JSON lines of the host commands the MCU handled: host wall time, type, fields, ack."""

    def __init__(self, path: str | None):
        self.file = open_fresh(path, 'a', buffering=1) if path else None

    def command(self, now: float, msg, result: int) -> None:
        if not self.file:
            return
        fields = {k: v for k, v in vars(msg).items() if not k.startswith('_')}
        self.file.write(json.dumps({'host_s': wall_time(now), 'command': msg.TYPE.name,
                                    'result': result, **fields}) + '\n')

    def close(self) -> None:
        if self.file:
            self.file.close()


def run(args: argparse.Namespace) -> int:
    try:
        ground = _ground(args)
    except (OSError, ValueError) as exc:
        print(f'minirquad_sim: error: true ground: {exc}', file=sys.stderr)
        return 2
    stop = stop_on_signals()

    faults = FaultInjector(FaultConfig(
        garbage_rate=args.garbage_rate, drop_rate=args.drop_rate,
        corrupt_rate=args.corrupt_rate, latency_ms=args.latency_ms, jitter_ms=args.jitter_ms,
        disconnect_at=args.disconnect_at, disconnect_for=args.disconnect_for,
        reset_at=args.reset_at, seed=args.seed))
    control = FaultControl(args.fault_control) if args.fault_control else None
    recorder = _Recorder(args.record)
    pending_tel: list = []
    link = PtyLink(args.symlink, args.link_file)
    print(link.open(), flush=True)

    start = time.monotonic()
    config = McuConfig(telemetry_hz=args.telemetry_hz, power_hz=args.power_hz,
                       watchdog_s=args.watchdog, winch_deadman_s=args.winch_deadman,
                       clock_start_ms=args.clock_start_ms)
    commands = _CommandLog(args.command_log)
    try:
        mcu = _make_mcu(args, ground, config, start,
                        on_telemetry=lambda s, t, tel: pending_tel.append((s, t, tel)),
                        on_command=commands.command)
    except FirmwareLinkError:
        link.close()
        link.remove_links()
        raise
    queue: deque[tuple[float, bytes]] = deque()    # (release time, bytes), in order
    line_free_at = 0.0                             # UART pacing
    byte_time = 10.0 / args.pace_baud if args.pace_baud else 0.0
    reconnect_at: float | None = None
    reset_done = False
    watch = PlantWatch()

    def emit(data: bytes, now: float) -> str | None:
        release, wire, fault = faults.outgoing(data, now)
        if wire:
            queue.append((release, wire))
        return fault

    try:
        emit(mcu.notice(start), start)
        stop_at: float | None = None
        while True:
            now = time.monotonic()
            t = now - start
            if args.duration and t >= args.duration:
                break
            if stop.is_set():
                stop_at = now + max(0.0, args.linger) if stop_at is None else stop_at
                if now >= stop_at:
                    break
            # Scheduled faults.
            if (args.disconnect_at is not None and reconnect_at is None and link.master is not None
                    and t >= args.disconnect_at):
                link.close()
                queue.clear()
                reconnect_at = now + args.disconnect_for
                faults.counts['disconnect'] += 1
            if reconnect_at is not None and now >= reconnect_at and link.master is None:
                link.open()
                args.disconnect_at = None
            if control is not None:
                try:
                    live = control.poll(now, faults.config)
                except ValueError as exc:
                    print(f'minirquad_sim: fault control: {exc}', file=sys.stderr, flush=True)
                    live = None
                if live is not None:
                    faults.config = live
                    spec = {k: v for k, v in vars(live).items() if k in LIVE_FIELDS and v}
                    print(f'FAULTS {json.dumps(spec)} AT {wall_time(now):.6f}',
                          flush=True)
            if args.reset_at is not None and not reset_done and t >= args.reset_at:
                reset_done = True
                # A reset cuts the frame in flight: half a frame with no closing delimiter.
                cut = encode_frame(mcu.telemetry(), mcu.seq, mcu.clock_ms(now))
                queue.append((now, cut[:len(cut) // 2]))
                queue.append((now, mcu.reset(now, m.ResetCause.WATCHDOG)))
                faults.counts['reset'] += 1
            # Host bytes.
            data = link.read()
            if data:
                for frame_bytes in _split(mcu.receive(data, now)):
                    emit(frame_bytes, now)
            # MCU loop.
            tick_start = time.monotonic()
            ticked = mcu.tick(now)
            watch.tick(time.monotonic() - tick_start, mcu.robot, t)
            for kind, frame_bytes, _tel in ticked:
                fault = emit(frame_bytes, now)
                if kind == 'telemetry':
                    for s, tm, tel in pending_tel:
                        recorder.telemetry(s, tm, tel, fault if link.master is not None
                                           else 'disconnected', wall_time(now))
                    pending_tel.clear()
            # Release due bytes, paced like a UART if asked.
            while queue and queue[0][0] <= now and now >= line_free_at:
                _, wire = queue.popleft()
                if link.master is not None:
                    link.write(wire)
                if byte_time:
                    line_free_at = max(now, line_free_at) + len(wire) * byte_time
            wake = mcu.next_due()
            if queue:
                wake = min(wake, max(queue[0][0], line_free_at))
            if reconnect_at is not None and link.master is None:
                wake = min(wake, reconnect_at)
            timeout = max(0.0, min(wake - time.monotonic(), 0.05))
            if link.master is not None:
                try:
                    select.select([link.master], [], [], timeout)
                except (OSError, ValueError):
                    time.sleep(timeout)
            else:
                time.sleep(timeout)
    finally:                      # also when the firmware dies: no pty or link left behind
        link.close()
        link.remove_links()
        recorder.close()
        commands.close()
        mcu.close()
        if isinstance(ground, BackgroundGround):
            ground.close()
        body = getattr(mcu.robot, 'physics', None)
        if isinstance(body, BackgroundPhysics):
            watch.behind_s = body.behind_s
            body.close()
    report = {'mcu': args.mcu, 'faults': dict(faults.counts), 'resets': mcu.resets,
              'rx_crc_errors': mcu.rx_crc_errors, **watch.report()}
    if isinstance(mcu, FirmwareMcu):     # how well the firmware kept up with the wall clock
        report.update(exchanges=mcu.exchanges, late_exchanges=mcu.late)
    print(json.dumps(report), flush=True)
    return 0


class PlantWatch:
    """What the simulator says about its plant keeping time, on stderr as it happens and in
    its exit report: loop turns longer than LATE_TICK_S, the physics body stopping, and the
    body running behind the wall clock (physics_worker.py)."""

    def __init__(self) -> None:
        self.late_ticks, self.worst_tick_s = 0, 0.0
        self.stopped = ''           # why the physics stopped, once said
        self.behind_said_s = 0.0
        self.behind_s = 0.0         # the most the body ran behind (set at the end)

    def tick(self, tick_s: float, robot, t: float) -> None:
        """After one MCU loop turn of tick_s seconds at simulator time t."""
        if tick_s > LATE_TICK_S:
            # the plant fell behind the wall clock: the host sees no telemetry meanwhile
            self.late_ticks += 1
            self.worst_tick_s = max(self.worst_tick_s, tick_s)
            print(f'minirquad_sim: the plant took {tick_s * 1e3:.0f} ms at t {t:.2f} s '
                  f'(mode {robot.mode.name})', file=sys.stderr, flush=True)
        body = getattr(robot, 'physics', None)   # the MCU's robot is new after a reset
        if body and body.failed and body.failed != self.stopped:
            # the plant froze: say so where a person reads the simulator's log
            self.stopped = body.failed
            print(f'minirquad_sim: physics stopped: {body.failed}', file=sys.stderr,
                  flush=True)
        if isinstance(body, BackgroundPhysics):
            self.behind_said_s = report_lag(body.behind_now_s, self.behind_said_s, t)

    def report(self) -> dict:
        out: dict = {}
        if self.stopped:
            out['physics_stopped'] = self.stopped
        if self.late_ticks:
            out.update(late_ticks=self.late_ticks,
                       worst_tick_ms=round(self.worst_tick_s * 1e3, 1))
        if self.behind_s:
            out['physics_behind_s'] = round(self.behind_s, 3)
        return out


def report_lag(lag: float, said: float, t: float) -> float:
    """Say on stderr that the physics body runs `lag` s behind the wall clock (its
    telemetry describes a body that far in the past) when it is BEHIND_REPORT_S beyond what
    was `said` last; returns what is said now (0 once it has caught up)."""
    if lag > said + BEHIND_REPORT_S:
        print(f'minirquad_sim: the physics runs {lag:.1f} s behind the wall clock at t '
              f'{t:.2f} s', file=sys.stderr, flush=True)
        return lag
    return 0.0 if lag == 0.0 else said


def _make_mcu(args: argparse.Namespace, ground, config: McuConfig, start: float,
              on_telemetry, on_command=None) -> SimMcu | FirmwareMcu:
    """The Python reference MCU, or the compiled firmware driving the plant (which handles
    the host's commands itself: no command log)."""
    if args.mcu == 'firmware':
        return FirmwareMcu(robot_factory=lambda: PlantRobot(
            ground=ground, winch=MotorWinch(sled_mass=args.sled_mass)),
            config=config, on_telemetry=on_telemetry, now=start, binary=args.firmware)
    poses = GaitPoses.for_sled(args.sled_mass) if args.body == 'scripted' else None
    bodies: list[BackgroundPhysics] = []

    def robot() -> SimRobot:
        # a reset powers up a new robot: the old body's worker ends with it
        while bodies:
            bodies.pop().close()
        inline = _physics(args)
        body = None if inline is None else BackgroundPhysics(inline)
        if body is not None:
            bodies.append(body)
        return SimRobot(ground=ground, winch=WinchSled(sled_mass=args.sled_mass),
                        physics=body, gait_poses=poses, physics_walk=args.body == 'physics')
    return SimMcu(robot_factory=robot, config=config, on_telemetry=on_telemetry, now=start,
                  on_command=on_command)


def _physics(args: argparse.Namespace) -> PhysicsBody | None:
    """A freshly powered robot's body (at start and at every MCU reset), or None for the
    scripted body. The simulator steps it in a worker process (physics_worker.py)."""
    if args.body == 'scripted':
        return None
    return PhysicsBody(robot=args.true_robot, anchor=args.anchor, medium=args.true_medium,
                       medium_scale=args.true_medium_scale, mass_scale=args.true_mass_scale)


def _ground(args: argparse.Namespace):
    """The true ground, built once so its cache outlives MCU resets (the scripted body's)."""
    if args.body != 'scripted' and args.mcu == 'firmware':
        # the firmware's plant drives velocity servos whose targets only the burrow sets: the
        # physics body's references would stop at stale targets
        raise ValueError(f'--body {args.body} runs with the Python MCU (--mcu python) only')
    if args.body != 'scripted':
        PhysicsBody(robot=args.true_robot, anchor=args.anchor, medium=args.true_medium,
                    medium_scale=args.true_medium_scale,
                    mass_scale=args.true_mass_scale)   # bad options fail here, before the link
        return make_ground('table')
    if args.ground != 'live':
        return make_ground(args.ground)
    ground = make_ground('live', robot=args.true_robot, medium=args.true_medium,
                         medium_scale=args.true_medium_scale, mass_scale=args.true_mass_scale,
                         anchor=args.anchor)
    ground.warm_up()   # compile and cache before the link opens: no stall mid-run
    # The worker is forked here, before the pty opens and the signal handlers are set.
    return BackgroundGround(ground) if args.ground_solver == 'worker' else ground


def _split(data: bytes) -> list[bytes]:
    """Replies come back concatenated; split them into frames so faults hit one frame each."""
    parts = []
    for seg in data.split(b'\x00'):
        if seg:
            parts.append(b'\x00' + seg + b'\x00')
    return parts


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The simulator's options from argv (default sys.argv[1:]), ROS arguments stripped."""
    return build_parser().parse_args(program_args(argv, 'minirquad_sim'))


def main(argv: list[str] | None = None) -> int:
    """Run the simulator; as the program (argv None) the process ends right after the pty is
    closed (node_main.finish: no slow native teardown)."""
    args = parse_args(argv)
    try:
        code = run(args)
    except (LinkPathError, FirmwareLinkError) as exc:
        print(f'minirquad_sim: error: {exc}', file=sys.stderr)
        code = 2
    if argv is None:
        finish(code)
    return code


if __name__ == '__main__':
    sys.exit(main())
