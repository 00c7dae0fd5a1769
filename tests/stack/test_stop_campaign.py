"""The stop promise under CPU load, over real DDS, measured on the MCU side.

minirquad_sim (the robot's MCU, on its own pty), bridge_node, capacity_node and behavior_node
run as processes; once the first tug reels in, two busy-loop processes at normal priority load
both cores for the rest of the test. Then, each time behavior_node is reeling at tug speed,
one fault starts:

- capacity_node killed (SIGKILL, then started again) or stopped (SIGSTOP; SIGCONT after the
  2 s grace);
- capacity_node answering each status without a usable value (it is stopped and this test
  publishes its estimates instead, stamped now: unsupported, degenerate, out_of_range,
  invalid_input, stale, an unknown code, ok without a value, assumed with an input the robot
  does not accept);
- bridge_node killed (started again) or stopped (0.8 s);
- 400 ms of latency, or 40 % of the MCU's frames lost (the simulator's --fault-control).

For each, the simulator's own record of its telemetry gives when the spool stood still and how
far it went from the reference instant t0: the sample time (header stamp) of the last estimate
capacity_node published (capacity_node faults); when the first non-value estimate went out
(statuses); the signal (bridge faults: nothing on the host can stop the winch after it; the
MCU's winch deadman does); the last sample the MCU sent before the latency started; the stamp
of the bridge's LinkState UNTRUSTED (loss: a loss can only be counted, the bridge counts it
over 1 s, and the test also bounds how long after the loss started that came). Promise: the
spool stands within 0.1 s and has reeled at most 5 mm. Every fault also leaves a cycle-report
row with its reason code (the cycle's summary event, and the CSV when behavior_node stops).

`make test` runs one fault of each kind (REPRESENTATIVE); `make test-campaign` (CI) runs every
class ``STOP_CAMPAIGN_RUNS`` times (10; STOP_CAMPAIGN_CLASSES picks some classes). The
simulator runs at nice -20: it stands for the robot's MCU, a separate processor that the host's
load does not slow down. The tug path's nodes run at nice -5 (TUG_PATH_NICE says why), the hogs
at 0. A command already on its way when the bridge is stopped or killed can still reach the
simulated MCU after the signal (it read it late); the MCU's deadman then counts from that
command, and so does the test (the figures from the signal are kept in the result).
"""
from __future__ import annotations

import collections
import csv
import json
import os
import re
import signal
import statistics
import sys
import threading
import time
from pathlib import Path

import pytest

# alone: its two CPU hogs would starve a stack another worker runs beside it, and that stack
# would add load the campaign's figures do not claim.
pytestmark = [pytest.mark.realtime, pytest.mark.alone, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
CAMPAIGN_RUNS = int(os.environ.get('STOP_CAMPAIGN_RUNS', '10'))
MAX_STOP_S = 0.1      # s from t0 to the spool standing
MAX_REEL_M = 0.005    # m reeled from t0
TUG_SPEED = 0.05      # m/s, behavior_node's tug_speed_m_s default
# The tug path (bridge_node, capacity_node, behavior_node) runs above best-effort work, as on the
# robot computer; the hogs at 0. At the same priority as the hogs and this shared machine's
# other load (load average ~20), the bridge starved and the link went stale every few seconds:
# the winch stayed stopped, but no tug resumed to fault again.
TUG_PATH_NICE = -5
MCU_NICE = -20        # the simulator stands for the MCU, a processor of its own

# status class -> (status_code, status word, capacity N, assumed inputs, expected reason)
STATUSES = {
    'unsupported': (6, 'unsupported', float('nan'), [], 'status_unsupported'),
    'degenerate': (7, 'degenerate', float('nan'), [], 'status_degenerate'),
    'out_of_range': (5, 'out_of_range', float('nan'), [], 'status_out_of_range'),
    'invalid_input': (4, 'invalid_input', float('nan'), [], 'status_invalid_input'),
    'stale': (3, 'stale', float('nan'), [], 'status_stale'),
    'unknown_code': (0, 'ok', 3.0, [], 'status_unknown_0'),
    'ok_without_value': (1, 'ok', float('nan'), [], 'no_value'),
    'assumed_phi': (2, 'assumed', 3.0, ['height', 'phi'], 'assumed_not_accepted'),
}
# On this shared 2-core machine under the hogs (load average 15-20 with the other work on it)
# the robot's own samples and the estimates are often late: the link goes stale or the attempt
# is aborted for late estimates before or after the injected fault, and the cycle's one reason
# code is then that one (the campaign's figures: docs/design/tug-safety.md). The row must exist
# and carry the fault's own code or one of these; the test prints how many carried their own.
# no_value: a value-carrying status next to no value, the other inconsistent-evidence code of
# behavior.evidence.TRANSIENT_REASONS (seen once for the `stale` class on a fresh clone, with
# the winch standing 75 ms / 3.8 mm after the fault). status_stale: capacity_node itself found
# one of its inputs older than its timeout, the same late data seen one hop earlier (also in
# TRANSIENT_REASONS; seen once for `capacity_killed` in the first run after the hogs started on
# a fresh clone, the winch standing 91 ms / 4.5 mm after the fault).
LATE = {'estimate_timeout', 'link_stale', 'no_value', 'status_stale'}
CLASSES = ['capacity_killed', 'capacity_stopped', *STATUSES, 'bridge_killed', 'bridge_stopped',
           'latency_400ms', 'loss_40pct']
# `make test` runs one of each kind of fault (about a minute and a half on a quiet machine: the
# suite must stay within 10 minutes); `make test-campaign` every class CAMPAIGN_RUNS times.
REPRESENTATIVE = ['capacity_killed', 'out_of_range', 'stale', 'bridge_stopped', 'latency_400ms',
                  'loss_40pct']
if os.environ.get('STOP_CAMPAIGN_CLASSES'):      # a subset, to look at some classes closely
    CLASSES = [c for c in CLASSES if c in os.environ['STOP_CAMPAIGN_CLASSES'].split(',')]
OWN = {'capacity_killed': 'estimate_timeout', 'capacity_stopped': 'estimate_timeout',
       **{k: v[4] for k, v in STATUSES.items()}, 'bridge_killed': 'link_stale',
       'bridge_stopped': 'link_stale', 'latency_400ms': 'link_stale',
       'loss_40pct': 'link_untrusted'}
REASONS = {cls: {own} | LATE for cls, own in OWN.items()}


def _ros2(pkg, exe, nice=None):
    """`ros2 run` of a node at the tug path's priority (TUG_PATH_NICE), or at ``nice``."""
    return ['nice', '-n', str(TUG_PATH_NICE if nice is None else nice), 'ros2', 'run', pkg, exe]


ENV = {'RCUTILS_LOGGING_USE_STDOUT': '1', 'RCUTILS_CONSOLE_OUTPUT_FORMAT': '{message}',
       'PYTHONUNBUFFERED': '1'}


class Stack:
    """The four processes; capacity_node and bridge_node can be killed and started again."""

    def __init__(self, tmp: Path, spawn):
        self.tmp, self.spawn = tmp, spawn
        self.tty, self.control = str(tmp / 'tty'), tmp / 'faults.json'
        self.record, self.commands = tmp / 'record.jsonl', tmp / 'commands.jsonl'
        self.control.write_text('{}')
        link = tmp / 'link'
        self.sim = spawn([*_ros2('minirquad_sim', 'minirquad_sim', MCU_NICE),
                          '--link-file', str(link), '--symlink', self.tty, '--sled-mass',
                          '0.4', '--record', str(self.record), '--command-log',
                          str(self.commands), '--fault-control',
                          str(self.control)],
                         stdout=open(tmp / 'sim.log', 'w'), stderr=open(tmp / 'sim.err', 'w'),
                         cwd=REPO)
        deadline = time.monotonic() + 20
        while not link.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert link.exists(), 'simulator did not start'
        self.start_bridge()
        self.start_capacity()
        argv = [*_ros2('rftgls_ros', 'behavior_node'), '--ros-args', '--params-file',
                'ros2_ws/params/behavior_node.yaml']
        for kv in ('sled_mass_kg:=0.4', 'cycles:=1000', 'max_aborts:=1000',
                   'evidence_wait_s:=60.0', 'link_wait_s:=60.0', 'walk_time_s:=2.5',
                   'idle_measure_time_s:=0.5', 'idle_settle_time_s:=0.3',
                   'burrow_modes:=table_ii', f'report_dir:={tmp / "report"}'):
            argv += ['-p', kv]
        self.behavior = spawn(argv, stdout=open(tmp / 'behavior.log', 'w'),
                              stderr=subprocess_stdout(), cwd=REPO, env=ENV)

    def start_bridge(self):
        self.bridge = self.spawn([*_ros2('minirquad_driver', 'bridge_node'), '--ros-args',
                                  '-p', f'port:={self.tty}'],
                                 stdout=open(self.tmp / 'bridge.log', 'a'),
                                 stderr=subprocess_stdout(), cwd=REPO, env=ENV)

    def start_capacity(self):
        self.capacity = self.spawn([*_ros2('rftgls_ros', 'capacity_node'), '--ros-args',
                                    '--params-file', 'ros2_ws/params/capacity_node.yaml',
                                    '-p', 'phi_topic:=/winch/phi'],
                                   stdout=open(self.tmp / 'capacity.log', 'a'),
                                   stderr=subprocess_stdout(), cwd=REPO, env=ENV)

    def faults(self, **rates) -> None:
        """Switch the simulator's per-frame faults (replaced atomically)."""
        tmp = self.control.with_suffix('.new')
        tmp.write_text(json.dumps(rates))
        tmp.replace(self.control)

    def fault_switches(self) -> list[tuple[dict, float]]:
        """(faults, host wall time s) of each switch the simulator applied."""
        text = (self.tmp / 'sim.log').read_text()
        return [(json.loads(a), float(b)) for a, b in re.findall(r'FAULTS (\{.*?\}) AT ([\d.]+)',
                                                                   text)]


def subprocess_stdout():
    import subprocess
    return subprocess.STDOUT


class Record:
    """The simulator's telemetry record (one JSON line per frame built), read as it grows."""

    def __init__(self, path: Path):
        self.path, self.rows, self._pos = path, [], 0

    def update(self) -> list[dict]:
        with open(self.path) as f:
            f.seek(self._pos)
            chunk = f.read()
        end = chunk.rfind('\n') + 1
        self._pos += len(chunk[:end].encode())
        for line in chunk[:end].splitlines():
            r = json.loads(line)
            self.rows.append((r['host_s'], r['spool'] * 1e-6, r['spool_v'] * 1e-6,
                              r['fault']))
        return self.rows

    def stop_after(self, t0: float) -> tuple[float, float] | None:
        """(s from t0 until the spool stood still, m reeled from t0), None while it still
        turns. The spool's stop instant is placed between the last sample that moved and the
        first that stood, from the distance between them at the last speed (the samples are
        10 ms apart; the position is exact)."""
        rows = self.update()
        k0 = next((k for k in range(len(rows) - 1, -1, -1) if rows[k][0] <= t0), None)
        if k0 is None:
            return None
        t_a, x_a, v_a, _ = rows[k0]
        x0 = x_a + v_a * (t0 - t_a)       # the spool at t0, at the speed it had
        if v_a == 0.0:
            return 0.0, 0.0
        for k in range(k0 + 1, len(rows)):
            t, x, v, _ = rows[k]
            if v == 0.0:
                tp, xp, vp, _ = rows[k - 1]
                t_stop = tp + min(t - tp, max(0.0, (x - xp) / vp)) if vp > 0 else t
                return max(0.0, t_stop - t0), max(0.0, x - x0)
        return None

    def last_sent_before(self, t: float) -> float:
        """host time of the last frame the MCU sent intact before t."""
        return max(r[0] for r in self.update() if r[0] < t and r[3] is None)


class Probe:
    """This test's ROS node: what behavior_node commands and says, capacity_node's estimates,
    the tension stamps, the bridge's link state; and a publisher of estimates."""

    def __init__(self, ctx):
        import rclpy
        from geometry_msgs.msg import WrenchStamped
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import (
            DurabilityPolicy,
            QoSProfile,
            ReliabilityPolicy,
            qos_profile_sensor_data,
        )
        from std_msgs.msg import String

        from rftgls_interfaces.msg import AnchorEstimate, LinkState, WinchCommand
        self.node = rclpy.create_node('stop_campaign_probe', context=ctx)
        latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.lock = threading.Lock()
        self.state, self.winch, self.winch_since = '', 0.0, time.monotonic()
        self.events: list[dict] = []
        self.estimates: list[tuple[float, float]] = []   # (sample s, received s), capacity_node's
        # the last estimates as received (a campaign that waits in vain prints them)
        self.recent: collections.deque[str] = collections.deque(maxlen=12)
        self.injecting = False
        self.links: list[tuple[float, int, float]] = []  # (stamp s, state, loss)
        self.tension_stamp = 0.0
        sub = self.node.create_subscription
        sub(String, '/behavior_node/state', self._on_state, latched)
        sub(String, '/behavior_node/events', self._on_event, 100)
        sub(WinchCommand, '/winch/command', self._on_winch, 10)
        sub(AnchorEstimate, '/capacity_node/estimate', self._on_estimate, 100)
        sub(LinkState, '/minirquad/link', self._on_link, latched)
        sub(WrenchStamped, '/winch/tension', self._on_tension, qos_profile_sensor_data)
        self.pub = self.node.create_publisher(AnchorEstimate, '/capacity_node/estimate', 10)
        self.AnchorEstimate = AnchorEstimate
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self):
        self._stop.set()
        self.thread.join(5)
        self.executor.shutdown()
        self.node.destroy_node()

    @staticmethod
    def _s(stamp) -> float:
        return stamp.sec + 1e-9 * stamp.nanosec

    def _on_state(self, msg):
        with self.lock:
            self.state = msg.data

    def _on_event(self, msg):
        with self.lock:
            self.events.append({**json.loads(msg.data), 'wall': time.time()})

    def _on_winch(self, msg):
        with self.lock:
            if (msg.speed_mps > 0.04) != (self.winch > 0.04):
                self.winch_since = time.monotonic()
            self.winch = msg.speed_mps

    def _on_estimate(self, msg):
        # An estimate is as old as the tension sample it is built on (a heartbeat estimate
        # carries capacity_node's clock): the newer of the two cannot be its sample time.
        with self.lock:
            self.recent.append(f'{time.time():.3f} {"injected " if self.injecting else ""}'
                               f'{msg.status} {msg.reason} stale {list(msg.stale_inputs)} '
                               f'{msg.detail[:160]}')
            if not self.injecting:
                self.estimates.append((min(self._s(msg.header.stamp), self.tension_stamp),
                                       time.time()))

    def _on_link(self, msg):
        with self.lock:
            self.links.append((self._s(msg.header.stamp), msg.state, msg.loss_ratio))

    def _on_tension(self, msg):
        self.tension_stamp = self._s(msg.header.stamp)

    def reeling_for(self) -> float:
        """s behavior_node has been commanding the tug speed in TUG (0 when not)."""
        with self.lock:
            if self.state != 'TUG' or self.winch <= 0.04:
                return 0.0
            return time.monotonic() - self.winch_since

    def publish_status(self, code, word, capacity, assumed) -> None:
        msg = self.AnchorEstimate(status_code=code, status=word, has_value=capacity == capacity,
                                  capacity_n=capacity, capacity_lower_n=capacity,
                                  tension_n=1.0, assumed_inputs=assumed)
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self.pub.publish(msg)

    def cycles_since(self, wall: float) -> list[dict]:
        with self.lock:
            return [e for e in self.events if e['kind'] == 'cycle' and e['wall'] >= wall]


def _last_winch_command(path: Path, before: float) -> tuple[float, float]:
    """(host time s, speed m/s) of the last WINCH command the MCU handled before ``before``."""
    last = (float('nan'), float('nan'))
    for line in path.read_text().splitlines():
        c = json.loads(line)
        if c['command'] == 'WINCH' and c['host_s'] < before:
            last = (c['host_s'], c.get('speed', float('nan')))
    return last


def _wait(cond, timeout: float, what: str, period: float = 0.01):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = cond()
        if got:
            return got
        time.sleep(period)
    raise AssertionError(f'timed out ({timeout:.0f} s) waiting for {what}')


def _cpu_hogs(spawn, n=2):
    return [spawn([sys.executable, '-c', 'while True: pass']) for _ in range(n)]


# A fault starts once the tug has reeled for 0.25 s, wherever the sled is: now and then the
# sled arrives (arrive_length_m) in the same few milliseconds and the cycle ends `ok` with no
# reason before any fault reached the tug (seen once in 42 runs: the spool already standing at
# t0, the row (23, 'ok', '')). Such a run says nothing about the fault; the class runs again.
ARRIVAL_RETRIES = 2


def _arrived_first(result: dict) -> bool:
    """The run's cycle ended by the sled's arrival, no fault recorded: the fault missed."""
    return result['row'][1:] == ('ok', '')


def _one_run(cls: str, stack: Stack, probe: Probe, record: Record, spawn) -> dict:
    """Start fault `cls` mid-tug; return t0, the stop (s, m) and the recorded reason."""
    try:
        _wait(lambda: probe.reeling_for() >= 0.25, 240, f'a reeling tug before {cls}')
    except AssertionError as exc:   # what capacity_node said last, and behavior_node's state
        with probe.lock:
            said = '\n'.join(probe.recent) or 'no estimate received'
            state, events = probe.state, probe.events[-3:]
        raise AssertionError(f'{exc}; now {time.time():.3f}, behavior_node {state}, its last '
                             f'events {events}; capacity_node\'s last estimates:\n{said}') \
            from None
    since = time.time()
    out: dict = {'class': cls}
    if cls in ('capacity_killed', 'capacity_stopped'):
        stack.capacity.send_signal(signal.SIGKILL if cls == 'capacity_killed'
                                   else signal.SIGSTOP)
        signalled = time.time()
        time.sleep(0.3)        # every estimate already on its way has reached the probe
        with probe.lock:       # this run's: received in the last second before the signal
            recent = [s for s, got in probe.estimates if signalled - 1.0 <= got]
        out['t0'] = max(recent) if recent else signalled
    elif cls in STATUSES:
        code, word, cap, assumed, _reason = STATUSES[cls]
        stack.capacity.send_signal(signal.SIGSTOP)
        probe.injecting = True
        out['t0'] = time.time()
        end = time.monotonic() + 4.0       # a transient status aborts after the 2 s grace
        while time.monotonic() < end and not probe.cycles_since(since):
            probe.publish_status(code, word, cap, assumed)
            time.sleep(0.01)
        probe.injecting = False
    elif cls in ('bridge_killed', 'bridge_stopped'):
        out['t0'] = time.time()
        stack.bridge.send_signal(signal.SIGKILL if cls == 'bridge_killed'
                                 else signal.SIGSTOP)
    elif cls == 'latency_400ms':
        stack.faults(latency_ms=400)
        onset = _wait(lambda: stack.fault_switches()[-1][1]
                      if stack.fault_switches()[-1][0] else None, 5, 'the latency switch')
        time.sleep(0.3)
        out['t0'] = record.last_sent_before(onset + 1e-3)
    elif cls == 'loss_40pct':
        n_links = len(probe.links)
        stack.faults(drop_rate=0.4)
        onset = _wait(lambda: stack.fault_switches()[-1][1]
                      if stack.fault_switches()[-1][0] else None, 5, 'the loss switch')
        untrusted = _wait(lambda: next((x for x in probe.links[n_links:] if x[1] == 2), None),
                          10, 'LinkState UNTRUSTED')
        out['t0'], out['detected_after_s'], out['loss'] = \
            untrusted[0], untrusted[0] - onset, untrusted[2]
    out['stop'] = _wait(lambda: record.stop_after(out['t0']), 10, f'the spool standing ({cls})',
                        period=0.05)
    out['last_command'] = _last_winch_command(stack.commands, out['t0'] + out['stop'][0])
    if cls.startswith('bridge_') and out['last_command'][0] > out['t0']:
        # A command in flight at the signal reached the MCU after it (the simulated MCU, a
        # process on the loaded host, read it late): the deadman counts from that command.
        out['from_signal'] = out['stop']
        out['t0'] = out['last_command'][0]
        out['stop'] = _wait(lambda: record.stop_after(out['t0']), 10, 'the spool standing')
    print(f'[stop campaign] {cls}: t0 {out["t0"]:.3f}, winch standing after '
          f'{1e3 * out["stop"][0]:.0f} ms, {1e3 * out["stop"][1]:.2f} mm; the MCU handled its '
          f'last winch command {1e3 * (out["t0"] - out["last_command"][0]):+.0f} ms before t0 '
          f'({out["last_command"][1]:.3f} m/s)', flush=True)
    # Clear the fault once the winch stood; the row comes when the attempt or cycle ends.
    if cls in ('capacity_killed', 'capacity_stopped'):
        # Past the 2 s grace: the attempt is aborted (or, if the robot's link went stale with
        # it on this loaded host, the cycle's row keeps the reason when the cycle ends).
        time.sleep(max(0.0, since + 2.5 - time.time()))
        if cls == 'capacity_killed':
            stack.capacity.wait(5)
            stack.start_capacity()
        else:
            stack.capacity.send_signal(signal.SIGCONT)
    elif cls in STATUSES:
        stack.capacity.send_signal(signal.SIGCONT)
    elif cls == 'bridge_killed':
        stack.bridge.wait(5)
        stack.start_bridge()
    elif cls == 'bridge_stopped':
        time.sleep(max(0.0, since + 0.8 - time.time()))
        stack.bridge.send_signal(signal.SIGCONT)
    elif cls == 'latency_400ms':
        time.sleep(max(0.0, since + 1.0 - time.time()))
        stack.faults()
    elif cls == 'loss_40pct':
        time.sleep(0.3)
        stack.faults()
    try:
        row = _wait(lambda: probe.cycles_since(since), 120, f'the cycle row after {cls}')[0]
    except AssertionError as exc:     # say where behavior_node was instead
        tail = (stack.tmp / 'behavior.log').read_text().splitlines()[-12:]
        raise AssertionError(f'{exc}; behavior_node last said:\n' + '\n'.join(tail)) from None
    out['row'] = (row['cycle'], row['outcome'], row['reason'])
    print(f'[stop campaign] {cls}: row {out["row"]}', flush=True)
    return out


@pytest.mark.timeout(900)
def test_each_kind_of_fault_stops_the_winch_in_time_under_cpu_load(tmp_path, spawn, stop,
                                                                    ros_context):
    _campaign(tmp_path, spawn, stop, ros_context, REPRESENTATIVE, 1)


@pytest.mark.campaign
@pytest.mark.timeout(300 + 900 * CAMPAIGN_RUNS)
def test_every_fault_class_stops_the_winch_in_time_under_cpu_load(tmp_path, spawn, stop,
                                                                     ros_context):
    _campaign(tmp_path, spawn, stop, ros_context, CLASSES, CAMPAIGN_RUNS)


def _campaign(tmp_path, spawn, stop, ros_context, classes: list[str], runs: int) -> None:
    stack = Stack(tmp_path, spawn)
    probe = Probe(ros_context)
    record = Record(stack.record)
    results: list[dict] = []
    missed: list[dict] = []      # runs whose tug ended by the sled's arrival (_arrived_first)
    try:
        _wait(lambda: probe.reeling_for() >= 0.25, 120, 'the first tug')
        hogs = _cpu_hogs(spawn)
        t_start = time.monotonic()
        for _run in range(runs):
            for cls in classes:
                for _try in range(1 + ARRIVAL_RETRIES):
                    got = _one_run(cls, stack, probe, record, spawn)
                    if not _arrived_first(got):
                        break
                    print(f'[stop campaign] {cls}: the sled arrived before the fault reached '
                          'the tug; the class runs again', flush=True)
                    missed.append(got)
                results.append(got)
        wall = time.monotonic() - t_start
        for h in hogs:
            stop(h)
        stop(stack.behavior)               # SIGINT: the CSV report is written
    finally:
        probe.close()
    lines = []
    for cls in classes:
        got = [r for r in results if r['class'] == cls]
        secs = [r['stop'][0] for r in got]
        mm = [1e3 * r['stop'][1] for r in got]
        lines.append(f'{cls:18s} n {len(got):2d}  stop s max {max(secs):.3f} median '
                     f'{statistics.median(secs):.3f}  reel mm max {max(mm):.2f}  rows with '
                     f'{OWN[cls]} {sum(r["row"][2] == OWN[cls] for r in got)}/{len(got)}, '
                     f'reasons {sorted({r["row"][2] for r in got})}'
                     + (f'  detected {max(r["detected_after_s"] for r in got):.2f} s after'
                        if cls == 'loss_40pct' else ''))
    print(f'\n[stop campaign] {runs} run(s) per class, {wall:.0f} s under two CPU hogs, '
          f'{len(missed)} run(s) again after the sled arrived first\n' + '\n'.join(lines))
    for r in results:
        assert r['stop'][0] <= MAX_STOP_S and r['stop'][1] <= MAX_REEL_M, (r, lines)
        assert r['row'][2] in REASONS[r['class']], (r, lines)
        if r['class'] == 'loss_40pct':
            # A loss is counted over the bridge's 1 s trust window: 10 % of it is 0.25 s at
            # 40 %, plus its 50 ms check and the load.
            assert r['detected_after_s'] <= 0.6 and r['loss'] >= 0.10, r
    rows = list(csv.DictReader(open(tmp_path / 'report' / 'cycle_report.csv')))
    by_cycle = {int(r['cycle']): (r['outcome'], r['reason']) for r in rows}
    for r in results + missed:            # the CSV holds the same row, reason and all
        assert by_cycle.get(r['row'][0]) == r['row'][1:], (r, rows)
