"""A slip is never forgotten, over real DDS: minirquad_sim (the true sand 50 % weaker than the
stack's map), bridge_node, capacity_node and behavior_node as processes (test_behavior_e2e.py).

The 800 g tug in DH (the choice on the map's lower bound: 4.73 N against 3.92 N needed) slips;
nothing is stronger than DH, so the answer is a stop. Once the simulated anchor has slipped 0.5 mm
under the tug, a 0.4 s link gap is injected: the simulator's whole MCU loop stands still
(``stall``: no telemetry and no command handled, what a stalled ground solver did in the
field) or the pty is unplugged (``unplug``). The stack must detect the slip, record it in the
cycle report's row with its reason code and answer it by the slip policy.

Each case is one run (about 25 s), all in `make test-campaign` (`make test` runs the gap-free slip
in test_tug_safety_e2e.py); docs/design/tug-safety.md gives the 10-run figures.
"""
from __future__ import annotations

import csv
import re
import sys
from pathlib import Path

import pytest
from test_behavior_e2e import run_stack

# Real-time end-to-end stacks: `make test` runs them in its real-time
# phase, two stacks at a time (pytest.ini, Makefile).
pytestmark = pytest.mark.realtime

HERE = Path(__file__).resolve().parent
GAP_AFTER_SLIP_M = 0.0005
SLED_KG = 0.8       # DH; lighter sleds get DL, which in this sand digs itself in


def slip_run(tmp_path, spawn, stop, gap: str | None):
    """One 800 g cycle on sand x 0.5 with an optional link gap during the slip; returns the
    behaviour log, the cycle report rows and the simulator's output."""
    sim = [sys.executable, str(HERE / 'test_behavior_e2e.py'), '--heavier-at', '99',
           '--heavier-mass', str(SLED_KG)]
    args = ['--true-medium-scale', '0.5']
    if gap:
        sim += ['--gap-after-slip', str(GAP_AFTER_SLIP_M), '--gap-kind', gap, '--gap-for', '0.4']
        args += ['--disconnect-for', '0.4']
    # The shipped walk (2.5 s, as behavior_demo): the tether is slack when DH burrows.
    log = run_stack(tmp_path, spawn, SLED_KG, params=['walk_time_s:=2.5'], sim=sim,
                    sim_args=args, timeout=90)
    stop(run_stack.procs['sim'])
    report = tmp_path / 'report' / 'cycle_report.csv'
    rows = list(csv.DictReader(open(report))) if report.exists() else []
    return log, rows, (tmp_path / 'sim.log').read_text()


@pytest.mark.slow
@pytest.mark.campaign   # make test: the same slip without a gap, test_tug_safety_e2e.py
@pytest.mark.parametrize('gap', [None, 'stall', 'unplug'])
def test_e2e_slip_on_weak_sand_is_detected_and_recorded(tmp_path, spawn, stop, gap):
    log, rows, sim_out = slip_run(tmp_path, spawn, stop, gap)
    assert re.search(r'decision \(expected pose\): DH:', log), log
    if gap:
        assert f'GAP {gap}' in sim_out, sim_out
    assert 'anchor slip detected (slip_' in log, log
    # The row of the cycle in which the slip was seen keeps it (column slip), also when a
    # later abort ends that cycle (its reason is then the abort's). An attempt aborted for
    # late evidence before the slip is a row of its own, and the retry is the next cycle.
    slipped = [r for r in rows if r['slip'].startswith('slip_')]
    assert slipped and slipped[0]['mode'].startswith('DH'), (rows, log)
    assert slipped[0]['reason'] == slipped[0]['slip'] or slipped[0]['outcome'] == 'aborted'
