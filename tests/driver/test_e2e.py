"""End to end: the real bridge node (rclpy) and the simulated MCU over a real pty.

Each test runs the node in-process with a probe node in one executor, drives the robot
(a walking gait, so every telemetry frame carries different leg angles), injects one fault
in the simulator, and checks that the node keeps running, counts the fault, recovers, and
publishes only values the simulator really sent intact (compared in wire integers
against the simulator's record of every telemetry frame and its fate).
"""
from __future__ import annotations

import time

import pytest
from bridge_harness import Harness

from minirquad_driver.bridge_node import JOINT_NAMES
from minirquad_driver.protocol import messages as m

# Real-time: with three test workers on the two cores the disconnect and latency faults failed
# (a late last frame; a published frame missing from the simulator's record), so `make test`
# runs these in its real-time phase, two stacks at a time (pytest.ini, Makefile).
pytestmark = pytest.mark.realtime


def _published_subset_of_intact(h: Harness, sim) -> int:
    """Every published leg-angle tuple must be one the simulator sent intact."""
    intact, damaged = set(), set()
    for r in sim.records():
        (damaged if r['fault'] else intact).add(tuple(r['legs']))
    damaged -= intact
    n = 0
    for _, js in h.joints:
        assert list(js.name) == list(JOINT_NAMES)
        legs = tuple(round(p * 1e6) for p in js.position[:4])
        assert legs in intact, f'published {legs} was never sent intact'
        n += 1
    return n


def test_no_frame_lost_at_100hz(sim, harness):
    s = sim.start()
    h = harness(str(s.link))
    h.walk()
    h.spin(3.0)
    link = h.link()
    # Losses are counted by sequence number; the rate itself depends on how loaded the shared
    # machine is (the simulator is a Python process), so it is only checked loosely here and
    # measured properly by `python -m minirquad_sim.bridge_throughput`.
    assert link['dropped_frames'] == 0
    assert link['crc_errors'] == 0 and link['cobs_errors'] == 0
    assert link['telemetry_rate_hz'] >= 50.0
    # Nothing lost between node and probe: everything the node decoded so far arrives.
    decoded = h.node.core.counters.telemetry
    assert h.spin_until(lambda: len(h.joints) >= decoded, 3.0), (len(h.joints), decoded)
    n = _published_subset_of_intact(h, s)
    # Every frame the simulator built between the first and the last one we saw was
    # received (frames before the gait started are identical, so compare moving ones).
    seen = {tuple(round(p * 1e6) for p in js.position[:4]) for _, js in h.joints}
    recs = [tuple(r['legs']) for r in s.records()]
    counts = {}
    for legs in recs:
        counts[legs] = counts.get(legs, 0) + 1
    moving = [legs for legs in recs if counts[legs] == 1]
    idx = [i for i, legs in enumerate(moving) if legs in seen]
    assert len(idx) >= 120
    assert all(legs in seen for legs in moving[idx[0]:idx[-1] + 1])
    assert n >= 150
    assert h.energy and h.energy[-1] > 0.0 and h.energy == sorted(h.energy)
    assert h.power[-1].voltage == pytest.approx(7.4, abs=0.2) and h.power[-1].current < 0
    assert h.imu[-1].orientation.w == pytest.approx(1.0, abs=1e-3)   # walking: level body
    # Walking away from the sled stretches the rope until the sled slides: the tension stays
    # within [0, mu m g] = [0, 1.96] N (400 g sled, mu 0.5; a load cell may read 0.1 N low).
    assert len(h.tension) >= 0.9 * len(h.joints)
    assert all(-0.1 < w.wrench.force.x <= 1.97 for w in h.tension)
    assert h.diag and {st.name for st in h.diag[-1].status} >= {'minirquad_driver: link'}
    assert h.states[-1][1] == 'ok'
    # Time-synced on the MCU's acks: round trips bound the clock offset, nothing withheld.
    assert h.node.core.sync.round_trips >= 10
    time_status = h.node.core.diagnostics()[1]
    assert time_status.values['clock_synced'] and h.node.core.counters.telemetry > 150


FAULTS = {
    'garbage': ['--garbage-rate', '0.2'],
    'drop': ['--drop-rate', '0.05'],
    'corrupt': ['--corrupt-rate', '0.05'],
    'latency': ['--latency-ms', '30', '--jitter-ms', '5'],
    'disconnect': ['--disconnect-at', '5.0', '--disconnect-for', '1.0'],
    'reset': ['--reset-at', '4.0'],
    'wrap': ['--clock-start-ms', str(2**32 - 2500)],
}


#: Simulator time (s since its start) by which a scheduled fault is over, plus a margin.
#: The faults come late enough for a simulator and bridge that start slowly on a busy host
#: to be up before them.
FAULT_OVER_S = {'disconnect': 6.5, 'reset': 4.5}


@pytest.mark.parametrize('fault', sorted(FAULTS))
def test_fault_is_counted_and_survived(sim, harness, tmp_path, fault):
    # The bridge waits for the port before the simulator starts, so the simulator's fault
    # schedule (seconds since its start) is not eaten by the bridge's start-up on a busy host.
    h = harness(str(tmp_path / 'tty'), reconnect_period_s=0.05)
    s = sim.start(*FAULTS[fault])
    t_sim = time.monotonic()
    h.walk()
    h.spin(3.5)
    # Scheduled faults fire at a time since the simulator's start: make sure they did.
    # (The simulator's clock started before sim.start returned.)
    h.spin(FAULT_OVER_S.get(fault, 0.0) - (time.monotonic() - t_sim))
    # Recovered: telemetry is flowing again at the end, and the link is ok (fresh by
    # sample time, which a heavily loaded host may need a moment to catch up to).
    assert h.spin_until(lambda: h.states[-1][1] == 'ok' and not h.node.core.is_stale(), 3.0)
    link = h.link()
    t_end = time.monotonic()
    assert h.joints[-1][0] > t_end - 0.3
    _published_subset_of_intact(h, s)
    assert h.energy == sorted(h.energy)     # power > 0: energy never goes backwards
    rejected = link['crc_errors'] + link['cobs_errors'] + link['other_rejected']
    if fault == 'garbage':
        assert rejected > 0
        assert link['dropped_frames'] == 0   # the leading 0x00 keeps junk off good frames
    elif fault == 'drop':
        assert link['dropped_frames'] > 0 and rejected == 0
    elif fault == 'corrupt':
        assert link['crc_errors'] + link['cobs_errors'] > 0
        assert link['dropped_frames'] > 0
    elif fault == 'latency':
        assert link['rtt_median_ms'] >= 30.0
        assert link['dropped_frames'] == 0
    elif fault == 'disconnect':
        assert link['reconnects'] >= 1 and link['disconnects'] >= 1
        states = [st for _, st in h.states]
        assert 'stale' in states[1:] and states[-1] == 'ok'
        # Nothing is published while stale: a hole of about the unplug time.
        # (By sample time: receipt times compress the hole when the host runs behind.)
        times = [js.header.stamp.sec + 1e-9 * js.header.stamp.nanosec for _, js in h.joints]
        assert max(b - a for a, b in zip(times, times[1:])) > 0.8
    elif fault == 'reset':
        assert link['mcu_resets'] == 1
        assert h.node.core.energy.resets == 0       # the notice restarted the baseline
        assert link['dropped_frames'] == 0
    elif fault == 'wrap':
        assert link['clock_wraps'] == 1 and link['mcu_resets'] == 0
        assert h.node.core.energy.gaps == 0


def test_host_silence_stops_legs_and_winch_in_the_loop(sim, harness, tmp_path):
    """The host falls silent (the bridge stalls: no heartbeat, no command) while the robot
    walks and the winch pays out. With the winch deadman off, only the MCU's host watchdog
    can stop the winch: within 0.5 s of silence legs and spool must stand still, and stay so
    (the simulator's record of every telemetry frame it built is the evidence)."""
    from std_msgs.msg import Float64
    h = harness(str(tmp_path / 'tty'), reconnect_period_s=0.05)
    # The table ground: the live solver would fit each new pose the settling legs pass
    # through (a 1 degree grid), stalling the simulator; the ground is not under test here.
    s = sim.start('--winch-deadman', '0', '--ground', 'table')
    h.walk()
    h.winch.publish(Float64(data=-0.02))
    h.spin(1.5)
    silent_from = time.time()
    with h.node.core._lock:          # the bridge stalls: nothing is sent for 1.5 s
        time.sleep(1.5)
    silent_to = time.time()
    h.spin(0.5)
    recs = [r for r in s.records() if r['host_s'] is not None]
    before = [r for r in recs if silent_from - 0.5 < r['host_s'] < silent_from]
    stopped = [r for r in recs if silent_from + 0.8 < r['host_s'] < silent_to]
    assert len(before) > 20 and len(stopped) > 40
    # Moving before: the spool paid out and the legs turned.
    assert before[-1]['spool'] < before[0]['spool']
    assert any(abs(v) > 500 for r in before for v in r['vel'])
    # Stopped after 0.5 s + the settling of the hold (the firmware's: 0.27 s; see
    # tests/sim/test_mcu_contract.py): every leg below 20 mrad/s, the spool not moving.
    assert all(r['mode'] == int(m.Mode.WATCHDOG) for r in stopped)
    assert all(r['flags'] & int(m.Flag.WATCHDOG_TRIPPED) for r in stopped)
    assert all(abs(v) <= 20 for r in stopped for v in r['vel'])
    assert stopped[-1]['spool'] == stopped[0]['spool']
    assert h.node.core.counters.mcu_errors >= 1
    assert h.node.core.last_error.code == m.ErrorCode.HOST_WATCHDOG
