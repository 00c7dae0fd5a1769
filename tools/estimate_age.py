"""How old capacity_node's estimates are when behavior_node could act on them.

    python tools/estimate_age.py --duration 90 --out out/estimate_age.json

Run next to a stack (e.g. `behavior_demo`, same ROS_DOMAIN_ID). It subscribes like
behavior_node (capacity_node/estimate, winch/tension, behavior_node/state) and, for every
estimate, records on one clock (the ROS clock, s):

- period: receipt to receipt of consecutive estimates;
- age at receipt: receipt minus the sample time behavior_node gives the estimate (its stamp,
  never newer than the newest tension sample received: behavior_node.on_estimate);
- age before replacement: receipt of the next estimate minus this one's sample time, the
  largest age the evidence rule ever sees (the number `estimate_timeout_s` is compared with).

It prints percentiles (all estimates, and those received while behavior_node was in TUG) and
how many estimates a given timeout would have let expire, and the same two figures for the
bridge's tension samples (`tension_tug`: period and age at receipt). `hops_tug` splits each
estimate's age by the DDS source and reception timestamps of its message: sample -> published
by capacity_node, published -> received (DDS), received -> taken by this probe's callback
(a subscriber's own backlog). No decision is taken here.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
import rclpy
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from std_msgs.msg import String

from rftgls_conventions.safe_write import open_fresh
from rftgls_interfaces.msg import AnchorEstimate
from rftgls_ros.stamps import stamp_s

PCTS = (50, 90, 99, 99.9, 100)


class Probe(Node):
    def __init__(self) -> None:
        super().__init__('estimate_age_probe')
        self.t_tension = -math.inf
        self.state = ''
        self.rows: list[tuple[float, float, str]] = []     # (receipt s, sample s, state)
        self.tension_rows: list[tuple[float, float, str]] = []
        self.hops: list[tuple[float, float, float]] = []   # s: to publish, DDS, to callback
        self.create_subscription(WrenchStamped, 'winch/tension', self.on_tension,
                                 qos_profile_sensor_data)
        self.create_subscription(AnchorEstimate, 'capacity_node/estimate', self.on_estimate, 10)
        self.create_subscription(String, 'behavior_node/state', self.on_state, 10)

    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_tension(self, msg: WrenchStamped) -> None:
        t = stamp_s(msg.header.stamp)
        self.t_tension = max(self.t_tension, t)
        self.tension_rows.append((self.now_s(), t, self.state))

    def on_state(self, msg: String) -> None:
        self.state = msg.data

    def on_estimate(self, msg: AnchorEstimate, info) -> None:
        sample = min(stamp_s(msg.header.stamp), self.t_tension)
        now = self.now_s()
        self.rows.append((now, sample, self.state))
        if self.state == 'TUG':
            sent, got = info['source_timestamp'] * 1e-9, info['received_timestamp'] * 1e-9
            self.hops.append((sent - sample, got - sent, now - got))


def summary(rows: list[tuple[float, float, str]], timeouts: list[float],
            state: str | None = None) -> dict:
    """Percentiles over consecutive estimate pairs (both received in ``state``, if given)."""
    if len(rows) < 3:
        return {'estimates': len(rows)}
    t = np.array([r[0] for r in rows])
    s = np.array([r[1] for r in rows])
    pair = np.ones(len(rows) - 1, dtype=bool)
    if state is not None:
        st = np.array([r[2] == state for r in rows])
        pair = st[:-1] & st[1:]
    if pair.sum() < 2:
        return {'estimates': int(pair.sum())}
    period = np.diff(t)[pair]
    age = (t - s)[:-1][pair]
    before = (t[1:] - s[:-1])[pair]
    span = float(period.sum())
    pct = {name: {str(p): round(1e3 * float(np.percentile(v, p)), 1) for p in PCTS}
           for name, v in (('period_ms', period), ('age_at_receipt_ms', age),
                           ('age_before_replacement_ms', before))}
    return {'estimates': int(pair.sum()), 'span_s': round(span, 1), **pct,
            'expiries_per_min': {f'{1e3 * x:.0f}ms': round(60.0 * int(np.sum(before > x)) / span,
                                                            1) for x in timeouts}}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog='estimate_age', description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=60.0, help='s to listen')
    p.add_argument('--out', help='write the summary as JSON (a new file)')
    p.add_argument('--timeouts-ms', type=float, nargs='+', default=[40, 60, 80, 100])
    args = p.parse_args(argv)
    rclpy.init()
    probe = Probe()
    end = time.monotonic() + args.duration
    try:
        while time.monotonic() < end:
            rclpy.spin_once(probe, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):   # Ctrl-C or SIGINT: summarise
        pass
    timeouts = [1e-3 * x for x in args.timeouts_ms]
    report = {'all': summary(probe.rows, timeouts),
              'tug': summary(probe.rows, timeouts, 'TUG'),
              'tension_tug': summary(probe.tension_rows, timeouts, 'TUG'),
              'hops_tug': {name: {str(q): round(1e3 * float(np.percentile(col, q)), 1)
                                  for q in PCTS}
                           for name, col in zip(('sample_to_publish_ms', 'dds_ms',
                                                 'received_to_callback_ms'),
                                                np.array(probe.hops).T)} if probe.hops else {}}
    text = json.dumps(report, indent=1)
    print(text)
    if args.out:
        with open_fresh(args.out, 'w') as f:
            f.write(text + '\n')
    probe.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
