"""Teleop without ROS: the guard, the refusals, and the screen in every state (no `nan`, a
capacity that is not evidence greyed with its reason, the load only from two valid numbers).
The documented path with the simulator through a pseudo-terminal: test_teleop_documented.py."""
from __future__ import annotations

import itertools
import math
import re

import pytest

from rftgls_core.planning.burrowed import BurrowedPose
from rftgls_core.types import Provenance
from rftgls_ros.behavior.config import BehaviorConfig
from rftgls_ros.behavior.model import ANCHOR_MODES
from rftgls_ros.teleop import TeleopModel
from rftgls_ros.teleop.model import GREY

DEG = math.pi / 180
# A modelled SH pose (the shape of rftgls_core.planning.burrowed.mode_pose's answer).
SH_POSE = BurrowedPose(0.040, 0.003, 3.0 * DEG, 1.0 * DEG, 'burrow simulation of SH (test)')
POSES = {'SH': SH_POSE, 'DH': 'no shipped gait map answers (test)', 'DL': None}


def _valid(m: TeleopModel, tension: float, capacity: float, t: float = 0.0,
           lower: float | None = None) -> None:
    """A usable estimate at t, computed at the height the model sends; its lower bound is
    the capacity unless given."""
    m.tension, m.capacity, m.status, m.t_capacity = tension, capacity, 'ok', t
    m.capacity_lower = capacity if lower is None else lower
    m.capacity_h = m.height().value


def test_model_reels_in_below_limit():
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.02))]
    assert m.update(0.1) == []


def test_a_reel_in_carries_the_time_its_estimate_goes_stale():
    """The node sends reel_in_valid_until() with the set-point as the MCU's hold: the winch
    brakes when the estimate it rests on is stale_after old, even if teleop stalls."""
    m = TeleopModel()
    _valid(m, 1.0, 2.5, t=10.0)
    assert m.reel_in_valid_until() == 0.0                 # not reeling in: no deadline
    m.key('i', 10.1)
    assert m.reel_in_valid_until() == 10.0 + m.cfg.stale_after
    _valid(m, 1.0, 2.5, t=10.3)                          # a newer estimate moves it on
    assert m.reel_in_valid_until() == 10.3 + m.cfg.stale_after
    m.key('o', 10.4), m.key('o', 10.4)                    # paying out: no deadline
    assert m.winch < 0.0 and m.reel_in_valid_until() == 0.0


def test_model_refuses_reel_in_on_an_estimate_at_the_height_before_the_burrow():
    """After a burrow key the model sends the burrow's height; the estimate capacity_node
    computed at the standing height answers another question until a new one arrives."""
    m = TeleopModel(poses=POSES)
    _valid(m, 0.5, 2.5)
    standing = m.height().value
    m.key('3', 0.0)                                   # SH: its modelled height is sent
    assert m.height().value != standing
    v = m.verdict()
    assert (v.usable, v.reason) == (False, 'estimate_other_height'), v
    assert m.key('i', 0.0) == [] and 'refusing to pull harder' in m.message
    _valid(m, 0.5, 2.5)                               # the estimate at the new height
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]


def test_model_guard_needs_override_and_shows_red():
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    m.key('i', 0.0)
    m.tension = 2.1                                     # 84 % > 80 %
    assert m.update(0.1) == [('winch', 0.0)]
    assert m.key('i', 0.1) == [] and 'override' in m.message and m.alert
    assert '\x1b[1;31m' in ''.join(m.screen())
    m.key('!', 0.2)
    assert m.key('i', 0.3) == [('winch', pytest.approx(0.01))]
    assert 'OVERRIDE' in ''.join(m.screen())
    assert m.update(6.0) == [('winch', 0.0)]            # override expired (5 s)


def test_model_guard_trips_at_80_percent_of_the_lower_bound_not_the_point_estimate():
    """capacity 2.5 N, lower bound 1.5 N: 1.3 N is 52 % of the point estimate (the old
    guard would reel on) but 87 % of the lower bound, the number a decision uses."""
    m = TeleopModel()
    _valid(m, 1.0, 2.5, lower=1.5)                      # 67 % of the lower bound
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
    m.tension = 1.3
    assert m.tension / m.capacity < m.cfg.limit_fraction
    assert m.update(0.1) == [('winch', 0.0)]
    assert 'tension 87 % of the lower bound: winch stopped' in m.message, m.message
    assert m.key('i', 0.1) == [] and 'of the lower bound >= 80 %' in m.message
    text = _plain(m.screen())
    assert re.search(r'capacity\s+2\.50 N\s+lower bound\s+1\.50 N', text), text
    assert re.search(r'\]\s+87 % of the lower bound', text), text
    assert re.search(r'margin\s+0\.20 N', text), text    # lower bound - tension
    m.tension = 1.19                                    # 79 % of the lower bound: reels in
    assert m.key('i', 0.2) == [('winch', pytest.approx(0.01))]


@pytest.mark.parametrize('lower', [math.nan, math.inf, -math.inf, -0.1])
def test_model_refuses_reel_in_without_a_lower_bound(lower):
    """A valid point estimate without a finite lower bound is not evidence: i is refused
    with the reason, a running reel-in stops, the screen greys both numbers and says why."""
    m = TeleopModel()
    _valid(m, 0.5, 2.5)
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
    m.capacity_lower = lower
    assert not m.verdict().usable and m.verdict().reason == 'lower_bound_missing'
    assert m.update(0.05) == [('winch', 0.0)]
    assert m.key('i', 0.05) == [] and m.winch == 0.0
    assert 'refusing to pull harder' in m.message and 'without a lower bound' in m.message
    lines = m.screen()
    text = _plain(lines)
    assert 'not usable: ' + m.verdict().detail in text, text
    assert lines[1].count(GREY) >= 2, lines[1]          # capacity and lower bound greyed
    assert re.search(r'lower bound\s+--  N' if math.isinf(lower) or math.isnan(lower)
                     else r'lower bound\s+-0\.10 N', text), text
    assert re.search(r'-- % of the lower bound \(no valid lower bound\)', text), text


def test_model_zero_lower_bound_holds_the_guard():
    """A lower bound of 0 N leaves nothing to pull against: i needs the override."""
    m = TeleopModel()
    _valid(m, 0.1, 2.5, lower=0.0)
    assert m.key('i', 0.0) == [] and 'lower bound 0 N, nothing to pull against' in m.message
    assert '-- % of the lower bound (0 N: nothing to pull on)' in _plain(m.screen())


def test_model_refuses_without_valid_status():
    m = TeleopModel()
    assert m.key('i', 0.0) == [] and 'refusing to pull harder' in m.message
    _valid(m, 1.0, 2.5)
    m.status = 'unsupported'
    assert m.key('i', 0.0) == []
    m.status = 'ok'
    m.key('i', 0.0)
    assert m.update(1.0) == [('winch', 0.0)]            # capacity older than 0.5 s: stale
    assert m.key('o', 1.0) == [('winch', pytest.approx(-0.01))]  # paying out always works
    assert m.key('x', 1.0) == [('winch', 0.0), ('estop', True)]


@pytest.mark.parametrize('status', ['extrapolated', 'assumed', 'out_of_range', 'stale',
                                    'degenerate', 'invalid_input'])
def test_model_stops_a_running_reel_in_on_any_status_but_measured_ok(status):
    # a clamped 'extrapolated' value or an 'assumed' input is not evidence.
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
    m.status = status                                   # the value stays a plausible 2.5 N
    assert m.update(0.05) == [('winch', 0.0)]
    assert m.key('i', 0.05) == [] and m.winch == 0.0


def _plain(lines: list[str]) -> str:
    return re.sub(r'\x1b\[[\d;]*m', '', '\n'.join(lines))


STATUSES = ['ok', 'assumed', 'stale', 'invalid_input', 'out_of_range', 'unsupported',
            'degenerate', 'extrapolated', '']
NUMBERS = [math.nan, math.inf, -math.inf, 0.0, 2.3]
LOWERS = [math.nan, math.inf, 0.0, 1.5]


@pytest.mark.parametrize('status', STATUSES)
def test_no_nan_on_the_screen_in_any_state(status):
    """Every combination of status, capacity, lower bound (missing, 0, valid), tension, slip
    twist, age, assumed inputs, override and e-stop: no 'nan' or 'inf' on the screen; capacity
    and lower bound always both shown ('--' when missing); the load percentage appears only
    when tension and lower bound are both valid; numbers that are not evidence are greyed and
    the reason is on the screen."""
    combos = itertools.product(NUMBERS, LOWERS, NUMBERS, [(math.nan,) * 3, (0.0, 0.0, 0.0),
                                                   (0.1, -0.2, 0.97)],
                               [0.0, 10.0], [None, frozenset(), frozenset({'phi'})],
                               [False, True], [False, True], [None, (), ('burrow',)])
    shown = 0
    for cap, lower, tension, twist, age, assumed, override, estop, unheard in combos:
        m = TeleopModel()
        m.status, m.capacity, m.tension, m.slip_twist = status, cap, tension, twist
        m.capacity_lower = lower
        m.t_capacity, m.assumed_inputs, m.unheard = 0.0, assumed, unheard
        m.capacity_h = m.height().value
        m.t = age
        if override:
            m.key('!', age)
        if estop:
            m.key('x', age)
        lines = m.screen()
        text = _plain(lines)
        assert not re.search(r'\bnan\b|\binf\b', text, re.IGNORECASE), text
        load = re.search(r'\]\s+(\d+) %', text)
        verdict = m.verdict()
        both_valid = verdict.usable and math.isfinite(tension) and lower > 0
        assert bool(load) == both_valid, text
        both = r'capacity\s+(-?[\d.]+|--)\s+N\s+lower bound\s+(-?[\d.]+|--)\s+N'
        assert re.search(both, text), text
        if not math.isfinite(lower):
            assert re.search(r'lower bound\s+--  N', text) and not verdict.usable, text
        if not verdict.usable:
            assert lines[1].count(GREY) >= 2 and 'not usable: ' + verdict.detail in text, text
            assert re.search(r'margin\s+--  N', text), text
        shown += 1
    assert shown == len(NUMBERS) ** 2 * len(LOWERS) * 3 * 2 * 3 * 2 * 2 * 3


def test_an_assumed_input_is_named_and_refused_unless_accepted():
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    m.status, m.assumed_inputs = 'assumed', frozenset({'phi'})
    assert m.key('i', 0.0) == []
    assert 'assumed inputs phi not in accept_assumed_inputs' in m.message
    assert 'assumed inputs phi' in _plain(m.screen())
    m.cfg.accept_assumed_inputs = ('phi',)       # the documented opt-in
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]


def _settle(m: TeleopModel, mode: str, t: float = 0.0) -> None:
    """Burrow `mode` and hold its Table II final leg angles for 1 s."""
    m.key('123'[['DH', 'DL', 'SH'].index(mode)], t)
    final = ANCHOR_MODES[mode].final
    m.anchor.legs(*final, t)
    m.anchor.legs(*final, t + 1.0)


def test_a_burrowed_height_is_modelled_with_its_band_until_the_pitch_disagrees():
    m = TeleopModel(poses=POSES)
    h = m.height()
    assert (h.value, h.provenance) == (m.cfg.h_stand, Provenance.ASSUMED)   # standing
    _settle(m, 'SH')
    h = m.height()
    assert (h.value, h.band, h.provenance) == (0.040, 0.003, Provenance.MODELLED)
    assert m.anchor.pitch(3.5 * DEG, 0.5) is None             # not settled yet: no check
    assert m.anchor.pitch(3.5 * DEG, 1.0) is None             # inside 3 +- 1 deg
    assert 'pitch 3.5 deg measured, 3.0 +- 1.0 deg modelled' in _plain(m.screen())
    flag = m.anchor.pitch(5.0 * DEG, 1.1)                     # 1 deg outside the band
    assert flag and 'pitch 5.0 deg measured, 3.0 +- 1.0 deg modelled' in flag
    assert m.height().provenance is Provenance.ASSUMED        # refused unless accepted
    assert m.anchor.pitch(3.0 * DEG, 1.2) is None             # flagged once, and it stays
    assert m.height().provenance is Provenance.ASSUMED
    assert 'PITCH CHECK FAILED' in _plain(m.screen())
    _settle(m, 'SH', 2.0)                                     # a new burrow checks afresh
    assert m.height().provenance is Provenance.MODELLED and m.anchor.flag is None


def test_the_modelled_height_holds_only_at_the_final_pose():
    # The burrow simulation's height is the height of the mode's final pose: mid-burrow, or
    # with the legs stopped short of it (or moved off it later), it says nothing of the anchor.
    m = TeleopModel(poses=POSES)
    m.key('3', 0.0)
    h = m.height()
    assert (h.value, h.provenance) == (0.040, Provenance.ASSUMED)
    assert h.source.endswith('(legs not at its final pose)'), h.source
    retract = ANCHOR_MODES['SH'].retract
    m.anchor.legs(*retract, 0.5)                              # under way
    assert m.height().provenance is Provenance.ASSUMED
    final = ANCHOR_MODES['SH'].final
    tol = BehaviorConfig().burrow_tolerance_rad               # behavior_node's "arrived"
    m.anchor.legs(final[0], final[1] + 1.5 * tol, 0.8)        # short of it: not there
    assert m.height().provenance is Provenance.ASSUMED
    m.anchor.legs(final[0] + 0.9 * tol, final[1], 1.0)        # within it: there
    assert m.height().provenance is Provenance.MODELLED
    assert m.height().source == SH_POSE.source
    m.anchor.legs(0.0, 0.0, 2.0)                              # stood up (an MCU reset)
    assert m.height().provenance is Provenance.ASSUMED


@pytest.mark.parametrize('mode', ['DH', 'DL'])
def test_a_mode_without_a_modelled_pose_sends_its_table_ii_height_assumed(mode):
    m = TeleopModel(poses=POSES)
    _settle(m, mode)
    h = m.height()
    assert (h.value, h.band, h.provenance) == (ANCHOR_MODES[mode].h, ANCHOR_MODES[mode].h_band,
                                               Provenance.ASSUMED)
    assert m.anchor.pitch(40 * DEG, 2.0) is None              # no model to hold it against
    assert 'no modelled pose' in _plain(m.screen()) or 'no shipped gait map' in h.source


def test_an_ok_on_a_modelled_height_says_so_and_is_evidence():
    m = TeleopModel(poses=POSES)
    _settle(m, 'SH')
    _valid(m, 1.0, 4.2, lower=3.2)
    m.modelled_inputs = frozenset({'height'})
    assert m.verdict().usable
    assert 'status ok (height modelled)' in _plain(m.screen())
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]


@pytest.mark.parametrize('status', STATUSES)
def test_no_nan_on_the_screen_in_any_anchor_state(status):
    """Standing, burrowed with and without a modelled pose, settled or not, the pitch measured
    (finite or not) and flagged: no 'nan' or 'inf' on any screen line."""
    for mode, settle, pitch in itertools.product([None, 'DH', 'DL', 'SH'], [False, True],
                                                 [math.nan, math.inf, 3.0 * DEG, 9.0 * DEG]):
        m = TeleopModel(poses=POSES)
        m.status, m.capacity, m.capacity_lower, m.tension = status, 2.3, 1.5, 1.0
        m.modelled_inputs = frozenset({'height'})
        if mode:
            if settle:
                _settle(m, mode)
            else:
                m.key('123'[['DH', 'DL', 'SH'].index(mode)], 0.0)
        m.anchor.pitch(pitch, 2.0)
        text = _plain(m.screen())
        assert not re.search(r'\bnan\b|\binf\b', text, re.IGNORECASE), text
        assert re.search(r'anchor (-|DH|DL|SH)\s+h \d+(\.\d)?( \+- \d+\.\d)? mm', text), text
