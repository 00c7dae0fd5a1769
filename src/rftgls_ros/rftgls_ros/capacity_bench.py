"""capacity_bench: input message -> published prediction latency of capacity_node.

    ros2 run rftgls_ros capacity_bench [--map PATH | --live] [--in-process] [--n 1000]
                                       [--json]

Real rclpy and DDS on loopback (the ROS_DOMAIN_ID of the environment). capacity_node runs as
its own process, as deployed (`python -m rftgls_ros.capacity_node`, own interpreter and GIL),
next to a probe process that publishes the inputs and receives the outputs. With --in-process
the node spins in a thread of the probe's process instead: in-node timings straight from the
node object, but the node then shares the interpreter lock with the probe and the sender, so
its throughput is the three together's (a bench artefact a deployed node does not have).

The node is triggered by /joint_states in this benchmark and every message carries a slightly
different leg angle, so each output pays a real predictor query (no cache hit). With a map
the leg angle wiggles by 2 deg around DH; with --live (map_file '', live_method direct-warm,
the warm-started direct of docs/design/warm-direct.md) the legs follow the stream of
`rftgls bench`'s live section: sensor noise and slow burrowing, as a streaming robot sends.

Figures:
  node_latency_ms_median, node_latency_ms_p99: lock-step (publish one input, wait for its
      output), from the input message's DDS source timestamp to the moment the node has
      published all outputs for it, measured by the node itself (DDS hop in, executor
      wake-up, parsing, estimate, five publishes); read from its /diagnostics when it runs in
      its own process.
  node_processing_ms_median: the node's callback alone (parse, estimate, publish).
  probe_roundtrip_ms_median/_p99: input published -> output received by the probe (both DDS
      hops plus the probe's executor), for comparison.
  node_sustained_rate_hz: the highest tried input rate (100 .. 1000 Hz, free running for 1 s)
      at which every input was answered (rate_<R>hz_delivered: the fraction answered at each
      rate, waiting for a backlog to drain; rate_<R>hz_roundtrip_ms_median: how late).
  solver_*: with --live, the warm solver's own time per call and its fallback rate (over the
      node's last 1000 calls, so mostly the free-running phase).
  status_last: the node's status at the end (`ok`: it really solved).
  machine: where it ran (CPU, cores, SIMD, numba's target, load at the start), as
      `rftgls bench` records it.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile

from rftgls_conventions import LEG_JOINT_NAMES, pitch_to_quat_xyzw
from rftgls_core.benchmarks.machine import describe, machine_record
from rftgls_core.maps import resolve_map
from rftgls_node_base.dds_loopback import during_init
from rftgls_node_base.node_main import program_args

from .capacity.node_predictor import DEFAULT_MAP
from .capacity_node import CapacityNode
from .stamps import ns_stamp, stamp_ns

# The DH anchor of the paper's Table II; the bench wiggles theta_L1 around it.
DH = (0.034, math.radians(5.0), math.radians(-40.0), math.radians(30.0))
PHI = math.radians(-20.0)
RATES_HZ = (100, 200, 500, 1000)
WARMUP_INPUTS = 5       # lock-step inputs answered before the timed ones (run)
WARMUP_WAIT_S = 60.0    # s, the longest wait for each
# The drain after a free-running second: until every output is in, or none for DRAIN_IDLE_S.
DRAIN_IDLE_S, DRAIN_MAX_S = 0.5, 5.0


def small_map(directory: Path) -> Path:
    """A tiny real map around DH, for machines where the shipped map is not built yet."""
    from rftgls_core.maps import MapGrid, build_map, save_map
    grid = MapGrid.from_degrees([30.0, 40.0], [0.0, 10.0], [-50.0, -30.0], [20.0, 40.0],
                                [-20.0, 0.0], pulls=('backward',))
    data = build_map('minirquad', 'm90_sand', grid, method='twist-mesh', workers=1)
    return save_map(directory / 'bench_minirquad.h5', data)


class Rig:
    """capacity_node plus a probe node that publishes the inputs and records the outputs."""

    def __init__(self, context, map_file: str, live: bool = False,
                 separate_process: bool = False):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import WrenchStamped
        from sensor_msgs.msg import Imu, JointState
        from std_msgs.msg import Float64, String
        # phi on its topic: a measured phi, so the node runs its `ok` path (an assumed phi
        # would add the assumed-range lower bound to every new state)
        params = {'map_file': map_file, 'live_method': 'direct-warm', 'phi_rad': PHI,
                  'phi_topic': '/winch/phi',
                  'trigger_inputs': ['joint_states'], 'publish_rate_hz': 1.0,
                  'diagnostics_period_s': 0.2,
                  # every input answered: the bench measures whether the node keeps up
                  'trigger_max_queue_s': 0.0,
                  **{f'{n}_timeout_s': 30.0 for n in ('joint_states', 'pitch', 'tension',
                                                      'height', 'phi')}}
        self.proc: subprocess.Popen | None = None
        self.node: CapacityNode | None = None
        if separate_process:    # as deployed: the node in its own process (own GIL)
            argv = [sys.executable, '-m', 'rftgls_ros.capacity_node', '--ros-args']
            for k, v in params.items():
                argv += ['-p', f'{k}:={json.dumps(v)}']
            self.proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.DEVNULL)
        else:
            self.node = CapacityNode(context=context, parameter_overrides=[
                Parameter(k, value=v) for k, v in params.items()])
        self.probe = rclpy.create_node('capacity_bench_probe', context=context)
        self.pub_joints = self.probe.create_publisher(JointState, '/joint_states', 100)
        self.pub_imu = self.probe.create_publisher(Imu, '/imu/data', 10)
        self.pub_tension = self.probe.create_publisher(WrenchStamped, '/winch/tension', 10)
        self.pub_height = self.probe.create_publisher(Float64, '/winch/height', 10)
        self.pub_phi = self.probe.create_publisher(Float64, '/winch/phi', 10)
        self.last_ns = 0
        self.sent: dict[int, float] = {}    # stamp ns -> perf_counter at publish
        self.latency: dict[int, float] = {}  # stamp ns -> s
        self.probe.create_subscription(WrenchStamped, '/capacity_node/capacity', self.on_out,
                                       1000)
        self.status_last = ''
        self.capacity_last = math.nan
        self.probe.create_subscription(
            String, '/capacity_node/status', lambda m: setattr(self, 'status_last', m.data),
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.diag: dict[str, str] = {}   # the node's last /diagnostics values
        self.diag_time = -math.inf
        self.probe.create_subscription(DiagnosticArray, '/diagnostics', self.on_diag, 10)
        self.msg = JointState(name=list(LEG_JOINT_NAMES))
        self.Float64 = Float64
        self.stream = None
        if live:   # leg angles of the core bench's live stream (noise and slow burrowing)
            from rftgls_core.benchmarks.live import live_stream
            self.stream = [(s.theta_l1, s.theta_l2) for s in live_stream()]

    def on_out(self, msg) -> None:
        t = time.perf_counter()
        # the scalar capacity: the published vector C d(phi) along d(phi) = (-cos phi, sin phi)
        f = msg.wrench.force
        self.capacity_last = -f.x * math.cos(PHI) + f.z * math.sin(PHI)
        key = stamp_ns(msg.header.stamp)
        if key in self.sent:
            self.latency[key] = t - self.sent[key]

    def on_diag(self, msg) -> None:
        for st in msg.status:
            if st.name.startswith('capacity_node'):
                self.diag = {kv.key: kv.value for kv in st.values}
                self.diag_time = time.monotonic()

    def fresh_diag(self, executor, after: float, timeout: float = 5.0) -> dict[str, str]:
        """The node's diagnostics values from a message received after `after` (monotonic)."""
        if not spin_until(executor, lambda: self.diag_time > after, timeout):
            raise RuntimeError('capacity_node published no /diagnostics')
        return dict(self.diag)

    def static_inputs(self) -> None:
        from geometry_msgs.msg import WrenchStamped
        from sensor_msgs.msg import Imu
        imu = Imu()
        imu.header.frame_id = 'imu_link'     # capacity_node's imu_frame_id
        o = imu.orientation
        o.x, o.y, o.z, o.w = pitch_to_quat_xyzw(DH[1])
        self.pub_imu.publish(imu)
        self.pub_height.publish(self.Float64(data=DH[0]))
        self.pub_phi.publish(self.Float64(data=PHI))
        w = WrenchStamped()
        w.header.frame_id = 'winch_link'     # capacity_node's tension_frame_id
        w.wrench.force.x = 1.0
        self.pub_tension.publish(w)

    def send(self, k: int) -> int:
        """Publish joint_states number k (stamp = now, strictly increasing: capacity_node
        ages inputs by their stamps; theta_L1 wiggled by k)."""
        ns = max(time.time_ns(), self.last_ns + 1000)
        self.last_ns = ns
        self.msg.header.stamp = ns_stamp(ns)
        if self.stream is not None:
            # back and forth through the stream, so it never ends and never jumps
            n = len(self.stream)
            l1, l2 = self.stream[k % n if (k // n) % 2 == 0 else n - 1 - k % n]
        else:
            l1, l2 = DH[2] + math.radians(2.0) * math.sin(0.37 * k), DH[3]
        self.msg.position = [l1, l1, l2, l2]
        self.sent[ns] = time.perf_counter()
        self.pub_joints.publish(self.msg)
        return ns


def spin_until(executor, cond, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.005)
    return cond()


def spin_in_thread(executor, stop: threading.Event, period_s: float) -> threading.Thread:
    """Spin `executor` in a daemon thread (spin_once waits up to period_s) until `stop` is set."""
    def spin():
        while not stop.is_set():
            executor.spin_once(timeout_sec=period_s)

    th = threading.Thread(target=spin, daemon=True)
    th.start()
    return th


def run(map_file: str, n: int, in_process: bool = False) -> dict:
    # Where the figures were measured (the CPU, its load at the start), as `rftgls bench`
    # records it: a latency means little without the machine behind it.
    machine = machine_record()
    ctx = rclpy.Context()
    with during_init():
        rclpy.init(context=ctx, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    rig = Rig(ctx, map_file, live=not map_file, separate_process=not in_process)
    # In process, the node spins in its own thread with its own executor; the probe spins in
    # this thread. Otherwise the node is a child process (its own interpreter).
    node_ex = SingleThreadedExecutor(context=ctx)
    stop = threading.Event()
    if rig.node is not None:
        node_ex.add_node(rig.node)
    th = spin_in_thread(node_ex, stop, 0.05)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(rig.probe)
    where = 'in process' if in_process else 'own process'
    out: dict = {'predictor': (rig.node.estimator.predictor.name if rig.node is not None
                               else 'live:direct-warm' if not map_file else map_file)
                 + f' ({where})', 'machine': machine}
    try:
        pubs = (rig.pub_joints, rig.pub_imu, rig.pub_tension, rig.pub_height, rig.pub_phi)
        if not spin_until(ex, lambda: all(p.get_subscription_count() for p in pubs), 10.0):
            raise RuntimeError('capacity_node subscriptions were not discovered')
        if not spin_until(ex, lambda: rig.probe.count_publishers('/capacity_node/capacity'),
                          10.0):
            raise RuntimeError('capacity_node publisher was not discovered')
        # The node may match a publisher after its first message: repeat the static inputs
        # until it answers `ok` (a bench of `stale` answers would time no solving).
        for k in range(50):
            rig.static_inputs()
            rig.send(-1 - k)
            if spin_until(ex, lambda: rig.status_last.startswith('ok'), 0.2):
                break
        else:
            raise RuntimeError(f'capacity_node never answered ok '
                               f'(last status {rig.status_last!r})')
        # Warm-up, not timed: the first inputs after `ok` take the warm path, whose kernels a
        # fresh numba cache compiles there (seconds on a loaded machine: a bench that timed
        # them failed its 2 s wait in CI). Each gets WARMUP_WAIT_S.
        for k in range(WARMUP_INPUTS):
            key = rig.send(-100 - k)
            if not spin_until(ex, lambda k=key: k in rig.latency, WARMUP_WAIT_S):
                raise RuntimeError(f'no output for warm-up input {k} within '
                                   f'{WARMUP_WAIT_S:.0f} s')
        # Lock-step: one input, wait for its output, next input.
        rig.latency.clear()
        processing = []
        for k in range(n):
            key = rig.send(k)
            if not spin_until(ex, lambda k=key: k in rig.latency, 2.0):
                raise RuntimeError(f'no output for input {k}')
            if rig.node is not None:
                processing.append(rig.node.processing_s)
        rtt = sorted(v * 1e3 for v in rig.latency.values())
        if rig.node is not None:
            node_lat = sorted(v * 1e3 for v in list(rig.node.latency_s)[-n:])
            out['node_latency_ms_median'] = statistics.median(node_lat)
            out['node_latency_ms_p99'] = percentile(node_lat, 0.99)
            out['node_processing_ms_median'] = statistics.median(processing) * 1e3
        else:   # the node's own figures over its last 1000 outputs: the lock-step's
            diag = rig.fresh_diag(ex, time.monotonic())
            out['node_latency_ms_median'] = float(diag['input_to_output_ms_median'])
            out['node_latency_ms_p99'] = float(diag['input_to_output_ms_p99'])
            out['node_processing_ms_median'] = float(diag['processing_ms_median'])
        out['probe_roundtrip_ms_median'] = statistics.median(rtt)
        out['probe_roundtrip_ms_p99'] = percentile(rtt, 0.99)
        out.update(sustained(rig, ex, k0=n + 10))
        out['status_last'] = rig.status_last.split(':')[0] or 'unknown'
        out['capacity_last_N'] = rig.capacity_last
        if rig.node is not None:
            stats = getattr(rig.node.estimator.predictor, 'stats', None)
            solver = stats() if stats is not None else {}
        else:
            diag = rig.fresh_diag(ex, time.monotonic())
            solver = {k[len('solver_'):]: float(v) for k, v in diag.items()
                      if k.startswith('solver_')}
        out.update({f'solver_{k}': v for k, v in solver.items()})
    finally:
        stop.set()
        th.join(2.0)
        ex.shutdown()
        node_ex.shutdown()
        if rig.node is not None:
            rig.node.destroy_node()
        if rig.proc is not None:   # terminate, timed wait, kill (a node can ignore SIGTERM)
            rig.proc.terminate()
            try:
                rig.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                rig.proc.kill()
                rig.proc.wait()
        rig.probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return out


def sustained(rig: Rig, ex, k0: int) -> dict:
    """Free-running inputs at each rate of RATES_HZ for 1 s (the probe spins in a thread);
    an input counts as answered when its output arrives at all, however late: the drain
    wait ends when every one is in or none came for DRAIN_IDLE_S. Stops at the first rate
    with an unanswered input."""
    out: dict = {}
    stop_probe = threading.Event()
    tp = spin_in_thread(ex, stop_probe, 0.01)
    best = 0
    try:
        for rate in RATES_HZ:
            rig.latency.clear()
            rig.sent.clear()
            count = max(100, int(rate * 1.0))
            t0 = time.perf_counter()
            keys = []
            for i in range(count):
                target = t0 + i / rate
                while time.perf_counter() < target:
                    time.sleep(min(0.0005, max(0.0, target - time.perf_counter())))
                keys.append(rig.send(k0 + i))
            k0 += count + 10
            got, last_change, end = -1, time.monotonic(), time.monotonic() + DRAIN_MAX_S
            while time.monotonic() < end:
                now_got = sum(1 for key in keys if key in rig.latency)
                if now_got == count:
                    break
                if now_got != got:
                    got, last_change = now_got, time.monotonic()
                elif time.monotonic() - last_change > DRAIN_IDLE_S:
                    break
                time.sleep(0.02)
            lags = sorted(rig.latency[key] * 1e3 for key in keys if key in rig.latency)
            out[f'rate_{rate}hz_delivered'] = len(lags) / count
            out[f'rate_{rate}hz_roundtrip_ms_median'] = (statistics.median(lags) if lags
                                                         else math.nan)
            if len(lags) < count:
                break
            best = rate
    finally:
        stop_probe.set()
        tp.join(2.0)
    out['node_sustained_rate_hz'] = best
    return out


def percentile(sorted_values: list[float], q: float) -> float:
    return sorted_values[min(len(sorted_values) - 1, int(math.ceil(q * len(sorted_values))) - 1)]


def _default_map_installed() -> bool:
    try:
        resolve_map(DEFAULT_MAP)
    except ValueError:   # rftgls_core.maps.MapFileError
        return False
    return True


def main(args=None) -> int:
    ap = argparse.ArgumentParser(prog='capacity_bench', description=__doc__.split('\n')[0])
    ap.add_argument('--map', default='', help=f'map file (default: {DEFAULT_MAP} if built, '
                    'else a small map built for the bench)')
    ap.add_argument('--live', action='store_true',
                    help='live warm-started direct predictor (direct-warm), no map')
    ap.add_argument('--in-process', action='store_true',
                    help='run capacity_node in a thread of the bench process instead of its own '
                         'process (in-node timings from the node object; the node shares the '
                         'interpreter lock with the probe and the sender)')
    ap.add_argument('--n', type=int, default=1000, help='lock-step messages (default 1000)')
    ap.add_argument('--json', action='store_true', help='print JSON')
    ns = ap.parse_args(program_args(args, ap.prog))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rftgls_core  # src/rftgls_core/rftgls_core/__init__.py -> repository root
    profile = (Path(rftgls_core.__file__).resolve().parents[3] / 'ros2_ws' / 'params'
               / 'fastdds_localhost.xml')
    if profile.is_file():  # DDS sockets on 127.0.0.1 (docs/design/capacity-inputs.md)
        os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(profile))
        os.environ.setdefault('FASTDDS_DEFAULT_PROFILES_FILE', str(profile))
    note = ''
    with tempfile.TemporaryDirectory() as tmp:
        if ns.live:
            map_file = ''
        elif ns.map:
            map_file = ns.map
        elif _default_map_installed():
            map_file = DEFAULT_MAP
        else:
            map_file = str(small_map(Path(tmp)))
            note = f'{DEFAULT_MAP} not built: small map built for the bench'
        res = run(map_file, ns.n, ns.in_process)
    res['note'] = note
    if ns.json:
        print(json.dumps(res, indent=2, sort_keys=True))
        return 0
    units = {'node_latency_ms_median': ('ms', '<= 2 ms' if ns.live else '<= 1 ms'),
             'node_latency_ms_p99': ('ms', ''), 'node_processing_ms_median': ('ms', ''),
             'probe_roundtrip_ms_median': ('ms', ''), 'probe_roundtrip_ms_p99': ('ms', ''),
             'node_sustained_rate_hz': ('Hz', '>= 500 Hz, none dropped' if ns.live
                                        else '>= 100 Hz, none dropped')}
    for name, (unit, budget) in units.items():
        line = f'{name:<27} {res[name]:>9.3f} {unit:<3}'
        print(line + (f'  budget {budget}' if budget else ''))
    print(f'predictor: {res["predictor"]}' + (f' ({note})' if note else '')
          + f'; last status {res.get("status_last", "?")}')
    print(f'measured on: {describe(res["machine"])}')
    for k in sorted(res):
        if k.startswith('rate_') or k.startswith('solver_'):
            print(f'  {k:<32} {res[k]:.3f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
