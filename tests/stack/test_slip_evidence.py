"""A slip is never forgotten, without ROS: the anchor's slip references survive a link gap.

Closed loop with the simulator's robot model (tests/stack/plant.py) on a true sand 50 % weaker
than the stack's map: the 800 g tug in the mode the map's lower bound chooses (DH: 4.73 N
against 3.92 N needed) slips on and on (nothing is stronger than DH: the answer is a stop).
A 0.4 s link gap is injected while the anchor slips, at several points of the slip, in two
worst cases of what the MCU does meanwhile: it keeps reeling (a stalled host side: nothing
reaches it, nothing comes back) or it stops on its winch deadman (0.08 s) as the firmware does.
During the gap the machine sees only the frozen last observation with the link down. After it,
the machine must still detect the slip against the anchor's references, record it in the
cycle's row, learn from it and answer it by the slip policy (re-burrow stronger or stop).
"""
from __future__ import annotations

import dataclasses
import math

import pytest
from plant import Plant, run_loop, table_ii_machine

from minirquad_sim.ground import LiveGround
from rftgls_ros.behavior import State
from rftgls_ros.behavior.slip import SLIP_PITCH, SlipDetector

SLED_KG = 0.8             # DH; lighter sleds get DL, which in this sand digs itself in

GAP_S = 0.4               # the link gap the field campaign saw during a slip (0.24-0.40 s)
DEADMAN_S = 0.08          # the MCU's winch deadman (minirquad_sim --winch-deadman default)
# Where in the slip the gap starts: p's slip under the tug so far, m. Without a gap the stack
# detects this slip at 4.5 mm (the first case below, measured), so the onsets lie in the slip
# before detection.
NO_GAP_DETECT_M = 0.0045
ONSETS_M = (0.1e-3, 0.3e-3, 0.5e-3, 0.7e-3, 0.9e-3)


def _weak_sand_with_gap(predictor, onset_m, mcu):
    """SLED_KG, true sand x 0.5, one cycle; a GAP_S link gap once the tug slip reaches
    ``onset_m`` (None: no gap). mcu 'reels' keeps the last winch command through the gap,
    'deadman' stops the winch DEADMAN_S after the last command reached it."""
    m = table_ii_machine(predictor, sled_mass_kg=SLED_KG, cycles=1)
    plant = Plant(SLED_KG, predictor, ground=LiveGround(medium_scale=0.5))
    seen: dict = {}
    advance, apply = plant.advance, plant.apply

    def in_gap() -> bool:
        return 'gap_t' in seen and plant.t < seen['gap_t'] + GAP_S

    def gap_advance(dt):
        obs = advance(dt)
        if onset_m is not None and 'gap_t' not in seen and plant.tug_slip >= onset_m:
            seen['gap_t'], seen['frozen'] = plant.t, obs
        if in_gap():     # the host hears nothing: the last observation, link down
            return dataclasses.replace(seen['frozen'], t=plant.t, link_ok=False)
        return obs

    def gap_apply(cmd):
        if in_gap():     # nothing reaches the MCU
            late = plant.t - seen['gap_t'] >= DEADMAN_S
            cmd = dataclasses.replace(
                cmd, oneshots=[],
                winch=0.0 if mcu == 'deadman' and late else plant.robot.winch.command)
        apply(cmd)

    def watch(p, mach):
        if 'detect_t' not in seen and any(str(e.get('reason', '')).startswith('slip_')
                                          for e in mach.events if e['kind'] == 'warn'):
            seen['detect_t'], seen['slip_at_detect'] = p.t, p.tug_slip
            seen['mode'] = mach.mode

    plant.advance, plant.apply = gap_advance, gap_apply
    run_loop(m, plant, t_max=90, on_step=watch)
    return m, plant, seen


CASES = [(None, 'reels')] + [(x, mcu) for mcu in ('reels', 'deadman') for x in ONSETS_M]


@pytest.mark.parametrize('onset_m, mcu', CASES)
def test_slip_during_a_link_gap_is_detected_recorded_and_answered(predictor, onset_m, mcu):
    m, plant, seen = _weak_sand_with_gap(predictor, onset_m, mcu)
    texts = [e['text'] for e in m.events][-25:]
    if onset_m is not None:
        assert 'gap_t' in seen, texts                       # the gap did fall in the slip
        assert any('WAIT_LINK' in t for t in texts) or m.records, texts
    assert seen.get('mode') == 'DH', texts                  # detected, on the DH anchor
    rec = m.records[0]
    assert rec.reason.startswith('slip_'), (rec, texts)    # recorded in the cycle's row
    assert rec.slip == rec.reason, rec
    assert rec.mode.startswith('DH'), rec
    assert m.chooser.scale < 1.0                            # learned: the sand is weaker
    # answered by the policy: a stronger mode re-burrowed and the sled arrived, or stopped
    assert (rec.outcome == 'ok' and '+' in rec.mode) or rec.outcome == 'stopped', rec
    assert m.state == State.FINISHED, m.reason
    # The slip under the tug stays bounded: blind, the winch reels at most the gap (reels) or
    # the deadman (deadman) x the tug speed; the anchor cannot slip more than the rope taken
    # in, and after the gap the stack needs what it needs without one (NO_GAP_DETECT_M).
    blind = (GAP_S if mcu == 'reels' and onset_m is not None else DEADMAN_S) \
        * m.cfg.tug_speed_m_s
    bound = (onset_m or 0.0) + blind + NO_GAP_DETECT_M + 1e-3    # + 1 mm: one step's reel
    assert 0.0 < seen['slip_at_detect'] <= bound, (seen['slip_at_detect'], bound)
    assert plant.tug_slip <= bound + 1e-3, plant.tug_slip
    assert seen['slip_at_detect'] <= 0.020       # the stack's limit: a slip seen within 20 mm


def test_references_belong_to_the_anchor_not_the_attempt():
    d = SlipDetector()
    d.update(1.5, 0.000, 0.05, (-0.7, 0.5))                   # taut: references taken
    d.update(1.8, 0.002, 0.05 + math.radians(0.8), (-0.7, 0.5))
    d.new_pull()                                               # a tug restarted after a gap
    ev = d.update(1.0, 0.003, 0.05 + math.radians(1.6), (-0.7, 0.5))
    assert ev is not None and ev.reason == SLIP_PITCH          # 1.6 deg since the anchor's
    assert ev.peak_tension == 1.8                              # what the anchor held
    assert ev.pitch_lost == pytest.approx(math.radians(1.6))
    # a move seen without load (after a gap, winch braked) is measured the same way
    assert d.moved(0.05 + math.radians(1.2), None, 'after the gap').reason == SLIP_PITCH
    d.reset()                                                  # a new burrow: a new anchor
    assert d.moved(0.05 + math.radians(5.0), (0.0, 0.0), 'x') is None
