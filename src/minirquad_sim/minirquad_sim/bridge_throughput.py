"""Throughput of the bridge: the telemetry rate it sustains, sim -> pty -> node -> probe.

    python -m minirquad_sim.bridge_throughput --rates 100 200 500 1000 --seconds 5 \
        [--pace-baud 115200]

For each rate it starts ``minirquad_sim`` on a pty, runs the bridge node and a probe in
this process, and reports telemetry frames per second decoded by the node and received by
the probe on /joint_states, plus dropped frames and CPU time of this process. Needs the
ROS environment (``source tools/env.sh``); uses ROS_DOMAIN_ID from the environment.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from minirquad_driver.bridge_node import BridgeNode
from rftgls_node_base.dds_loopback import during_init


def run_one(rate: int, seconds: float, pace_baud: int) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix='mq-bench-'))
    link = tmp / 'tty'
    argv = [sys.executable, '-m', 'minirquad_sim.main', '--symlink', str(link),
            '--telemetry-hz', str(rate), '--power-hz', str(max(1, rate // 2)),
            '--pace-baud', str(pace_baud)]
    sim = subprocess.Popen(argv, stdout=subprocess.DEVNULL)
    try:
        while not link.exists():
            time.sleep(0.01)
        ctx = rclpy.Context()
        with during_init():
            rclpy.init(context=ctx)
        node = BridgeNode(context=ctx, parameter_overrides=[Parameter('port', value=str(link))])
        probe = rclpy.create_node('bench_probe', context=ctx)
        got = [0]
        probe.create_subscription(JointState, 'joint_states',
                                  lambda _m: got.__setitem__(0, got[0] + 1), 1000)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:           # warm-up
            ex.spin_once(timeout_sec=0.01)
        c0, g0, cpu0 = node.core.counters.telemetry, got[0], time.process_time()
        d0 = node.core.counters.dropped_frames
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            ex.spin_once(timeout_sec=0.01)
        dt = time.monotonic() - t0
        res = {'rate_hz': rate, 'decoded_hz': (node.core.counters.telemetry - c0) / dt,
               'published_received_hz': (got[0] - g0) / dt,
               'dropped_frames': node.core.counters.dropped_frames - d0,
               'cpu_percent': 100.0 * (time.process_time() - cpu0) / dt,
               'rtt_ms_median': node.core.diagnostics()[0].values['rtt_median_ms']}
        node.destroy_node()
        probe.destroy_node()
        ex.shutdown()
        rclpy.try_shutdown(context=ctx)
        return res
    finally:
        sim.send_signal(2)
        try:
            sim.wait(5)
        except subprocess.TimeoutExpired:
            sim.kill()
            sim.wait()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--rates', type=int, nargs='+', default=[100, 200, 500, 1000])
    p.add_argument('--seconds', type=float, default=5.0)
    p.add_argument('--pace-baud', type=int, default=0)
    a = p.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    print('| requested Hz | decoded Hz | received on /joint_states Hz | dropped | '
          'bridge process CPU % | heartbeat RTT median ms |')
    print('|---|---|---|---|---|---|')
    for r in a.rates:
        x = run_one(r, a.seconds, a.pace_baud)
        print(f"| {r} | {x['decoded_hz']:.1f} | {x['published_received_hz']:.1f} | "
              f"{x['dropped_frames']} | {x['cpu_percent']:.0f} | {x['rtt_ms_median']} |",
              flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
