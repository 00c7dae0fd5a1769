"""Teleop without ROS: the guard, the refusals, and the screen in every state (no `nan`, a
capacity that is not evidence greyed with its reason, the load only from two valid numbers).
The documented path with the simulator through a pseudo-terminal: test_teleop_documented.py."""
from __future__ import annotations

import itertools
import math
import re

import pytest

from rftgls_ros.teleop import TeleopModel
from rftgls_ros.teleop.model import GREY


def _valid(m: TeleopModel, tension: float, capacity: float, t: float = 0.0) -> None:
    m.tension, m.capacity, m.status, m.t_capacity = tension, capacity, 'ok', t


def test_model_reels_in_below_limit():
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.02))]
    assert m.update(0.1) == []


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


@pytest.mark.parametrize('status', STATUSES)
def test_no_nan_on_the_screen_in_any_state(status):
    """Every combination of status, capacity, tension, slip twist, age, assumed inputs,
    override and e-stop: no 'nan' or 'inf' on the screen; the load percentage appears only
    when tension and capacity are both valid; a capacity that is not evidence is greyed and
    the reason is on the screen."""
    combos = itertools.product(NUMBERS, NUMBERS, [(math.nan,) * 3, (0.0, 0.0, 0.0),
                                                   (0.1, -0.2, 0.97)],
                               [0.0, 10.0], [None, frozenset(), frozenset({'phi'})],
                               [False, True], [False, True], [None, (), ('burrow',)])
    shown = 0
    for cap, tension, twist, age, assumed, override, estop, unheard in combos:
        m = TeleopModel()
        m.status, m.capacity, m.tension, m.slip_twist = status, cap, tension, twist
        m.t_capacity, m.assumed_inputs, m.unheard = 0.0, assumed, unheard
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
        both_valid = verdict.usable and math.isfinite(tension) and cap > 0
        assert bool(load) == both_valid, text
        if not verdict.usable:
            assert GREY in lines[1] and 'not usable: ' + verdict.detail in text, text
            assert re.search(r'margin\s+--  N', text), text
        shown += 1
    assert shown == len(NUMBERS) ** 2 * 3 * 2 * 3 * 2 * 2 * 3


def test_an_assumed_input_is_named_and_refused_unless_accepted():
    m = TeleopModel()
    _valid(m, 1.0, 2.5)
    m.status, m.assumed_inputs = 'assumed', frozenset({'phi'})
    assert m.key('i', 0.0) == []
    assert 'assumed inputs phi not in accept_assumed_inputs' in m.message
    assert 'assumed inputs phi' in _plain(m.screen())
    m.cfg.accept_assumed_inputs = ('phi',)       # the documented opt-in
    assert m.key('i', 0.0) == [('winch', pytest.approx(0.01))]
