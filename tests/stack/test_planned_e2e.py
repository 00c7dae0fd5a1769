"""Planned burrows end to end over real DDS: minirquad_sim (scripted body: a gait run leg by leg
settles at the pose the burrow simulation predicts, minirquad_sim/gait_pose.py), bridge_node,
capacity_node and behavior_node with ``burrow_modes:=planned`` (test_behavior_e2e.py).

behavior_node picks the cheapest gait of its sled's gait map whose lower bound covers the need,
streams its leg targets (leg_targets -> SetLegs), publishes the predicted h as a modelled input
and tugs on capacity_node's live lower bound. With the true sand as the stack's, the gait holds
through three cycles; with the true sand 30 % weaker, the stack plans a stronger gait from its
lower bound or detects the slip within 20 mm, stops and re-plans (or refuses).
"""
from __future__ import annotations

import csv
import math
import os
import random
import re
import signal
import sys
import threading
from pathlib import Path

import pytest
from test_behavior_e2e import run_stack

pytestmark = pytest.mark.realtime

HERE = Path(__file__).resolve().parent
SLIP_LIMIT_M = 0.020


def _rows(tmp_path):
    path = tmp_path / 'report' / 'cycle_report.csv'
    return list(csv.DictReader(open(path))) if path.exists() else []


def _plans(log):
    """The 'plan' of every planned decision event (behavior_node logs the event text; the
    JSON goes on ~/events: the text carries the same numbers)."""
    return re.findall(r'decision \(planned pose\): (g[-\d/>]+|DH|DL|SH): cheapest sufficient '
                      r'planned gait \(([\d.]+) J, \w[^)]*\); lower bound ([\d.]+) N >= '
                      r'[\d.]+ x ([\d.]+) N / ([\d.]+) at 95%, holds with p ([\d.]+)', log)


def _replays(log):
    return re.findall(r'replayed over (\d+) measured leg samples from \(([-\d.]+), '
                      r'([-\d.]+)\) deg: h ([\d.]+) \+- ([\d.]+) mm, pitch [-\d.]+ \+- '
                      r'[\d.]+ deg \(plan: h ([\d.]+) mm', log)


def _heights_within_the_plans_band(replays):
    """Each replay from standing (>= 20 samples) lands within the plan's band of its h."""
    for n, l1, l2, h, band, h_plan in replays:
        assert int(n) >= 20 and abs(float(l1)) < 3.0 and abs(float(l2)) < 3.0, replays
        assert abs(float(h) - float(h_plan)) <= float(band), replays


def _replays_went_as_planned(log):
    """Every burrow's height is the burrow simulation over the legs the robot measured (its
    worker process), from standing, within the plan's band of the plan's h; the measured
    pitch agrees with it (no 'did not go as modelled')."""
    replays = _replays(log)
    assert replays and len(replays) == log.count('BURROW -> CHECK'), log
    _heights_within_the_plans_band(replays)
    assert 'did not go as modelled' not in log, log


@pytest.mark.slow
@pytest.mark.parametrize('sled', [0.4, pytest.param(0.6, marks=pytest.mark.campaign)])
def test_planned_gait_holds_three_cycles(tmp_path, spawn, sled):
    log = run_stack(tmp_path, spawn, sled, params=['burrow_modes:=planned', 'cycles:=3'],
                    timeout=150)
    plans = _plans(log)
    assert plans, log
    gait, energy, lower, need, stop_ratio, p = plans[0]
    # Under the margin guard (it stops at stop_ratio x the lower bound) the sled still moves.
    assert float(lower) * float(stop_ratio) >= float(need) and float(energy) > 0 \
        and float(p) > 0.95, plans
    # The gait ran leg by leg (no Table II burrow command) and the height is the prediction.
    assert 'check ' + gait + ' at the measured pose' in log, log
    _replays_went_as_planned(log)
    assert 'measured leg samples' in log.split('at the measured pose', 1)[1], log
    rows = _rows(tmp_path)
    assert [r['outcome'] for r in rows] == ['ok'] * 3, (rows, log)
    # The first cycle may burrow twice: capacity_node's live lower bound at the measured pose
    # can reject the cheapest plan (600 g: 2.83 N < 3.03 N) and the stack re-plans stronger.
    # The stack keeps that bound: later cycles burrow the gait that held, once.
    held = rows[0]['mode'].split('+')[-1]
    assert rows[0]['mode'].split('+')[0] == gait, rows
    assert [r['mode'] for r in rows[1:]] == [held, held], rows
    for r in rows:
        assert float(r['reel_lower_margin_n']) >= 0.0, rows       # never tugged below need
        assert 0.02 < float(r['h_pred_m']) < 0.06 and float(r['p_hold']) > 0.95, rows
    assert math.isclose(float(rows[0]['lower_n']), float(lower), rel_tol=0.01) \
        or '+' in rows[0]['mode'], rows


@pytest.mark.slow
def test_planned_on_weaker_sand_replans_or_stops_within_20_mm(tmp_path, spawn, stop):
    sim = [sys.executable, str(HERE / 'test_behavior_e2e.py'), '--heavier-at', '99',
           '--heavier-mass', '0.6']
    log = run_stack(tmp_path, spawn, 0.6, params=['burrow_modes:=planned', 'cycles:=1'],
                    sim=sim, sim_args=['--true-medium-scale', '0.7'], timeout=120)
    stop(run_stack.procs['sim'])
    sim_out = (tmp_path / 'sim.log').read_text()
    # The anchor's slip (from the first burrow on); a walk's feet slipping against the rope
    # (WALK_DRAG: the MCU walked on while a stalled host's payout was braked) is no anchor's.
    total = float(re.search(r'SLIP_TOTAL ([\d.]+)', sim_out).group(1))
    rows = _rows(tmp_path)
    assert rows, log
    plans = _plans(log)
    assert plans, log
    # The tug ran (the sled moved) and the anchor never slipped 20 mm under it.
    assert sum(float(r['sled_distance_m']) for r in rows) > 0.05, (rows, log)
    assert total < SLIP_LIMIT_M, f'slipped {1e3 * total:.1f} mm\n{log}'
    if 'anchor slip detected' in log:
        # Seen and stopped, then a stronger plan (the need over the learned scale) or none.
        assert len(plans) >= 2 or 'no planned gait suffices' in log, log
    # Never a reel-in on a lower bound below the need (however the cycle ended: under load
    # the link or the evidence may abort it, which is the tug-safety rule, not a failure).
    assert all(float(r['reel_lower_margin_n']) >= 0.0 for r in rows
               if r['reel_lower_margin_n'] not in ('', 'nan')), rows


class Stalls(threading.Thread):
    """Stops (SIGSTOP) one of the given processes at a time for 0.2-0.8 s, every 0.5-2 s
    (seeded), as an overloaded or virtualised host stalls a process; `stop()` continues them
    all and ends. `paused` counts the stalls."""

    def __init__(self, procs, seed):
        super().__init__(daemon=True)
        self.procs, self.rng, self.paused = procs, random.Random(seed), 0
        self._end = threading.Event()

    def run(self):
        while not self._end.wait(self.rng.uniform(0.5, 2.0)):
            proc = self.rng.choice(self.procs) if self.procs else None
            if proc is None or proc.poll() is not None:
                continue
            os.kill(proc.pid, signal.SIGSTOP)
            try:
                self._end.wait(self.rng.uniform(0.2, 0.8))
            finally:
                os.kill(proc.pid, signal.SIGCONT)
            self.paused += 1

    def stop(self):
        self._end.set()
        self.join(timeout=5.0)
        for proc in self.procs:
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGCONT)


@pytest.mark.slow
@pytest.mark.campaign
# The stack's own budget (run_stack below, 240 s) and its start and stop, not pytest.ini's
# 120 s: a burrow that a stall cuts after its legs dug starts over after a slacken and a
# step off (link_wait.py), 10-15 s more under stalls every 0.5-2 s; one seed in three then
# needed past 110 s for its three checks.
@pytest.mark.timeout(270)
@pytest.mark.parametrize('seed', [1, 2, 3])
def test_planned_burrows_keep_their_height_through_process_stalls(tmp_path, spawn, seed):
    """A loaded host stalls processes for hundreds of ms. With the simulator, the serial
    bridge and behavior_node stalled in turn (Stalls) through three planned cycles, every
    replayed height stays within the plan's band: the ramp waits for its legs and resumes
    where it stopped (gait_motion.RampClock) and the burrow proper starts with the legs at
    rest at standing. (The replayed pitch can still miss the scripted body's by 1-2 deg under
    stalls; the stack then says the burrow did not go as modelled and sends the height
    assumed, which is allowed here.) The run is watched until its third burrow is checked:
    under stalls every few seconds the tugs stop on stale evidence again and again (the
    tug-safety rule, tested by the stop campaign) and may not finish in any fixed time."""
    stalled = []

    def spawn_stalled(argv, **kwargs):
        proc = spawn(argv, **kwargs)
        if not any('capacity_node' in a for a in argv):
            stalled.append(proc)
        return proc
    stalls = Stalls(stalled, seed)
    stalls.start()

    def checked(log):
        return len(_replays(log)) + log.count("the plan's predicted pose stands")
    try:
        log = run_stack(tmp_path, spawn_stalled, 0.4,
                        params=['burrow_modes:=planned', 'cycles:=3'], timeout=240,
                        until=lambda log: checked(log) >= 3)
    finally:
        stalls.stop()
    assert stalls.paused >= 10, stalls.paused
    assert checked(log) >= 3, log
    _heights_within_the_plans_band(_replays(log))
