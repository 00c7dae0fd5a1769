"""A reel-in's evidence deadline on its way to the MCU: the bridge turns a WinchCommand's
``valid_until`` into the WINCH frame's hold (the time left when it is sent) and never resends a
held WINCH, whose hold would count again from a late copy's receipt
(src/minirquad_driver/PROTOCOL.md, "Winch deadman"). The MCUs' side:
tests/sim/test_mcu_contract.py and the firmware's own tests."""
from __future__ import annotations

import pytest

from minirquad_driver.bridge import BridgeConfig, BridgeCore, winch_command
from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder

NOW = 1.7e9


def test_the_hold_is_the_time_the_evidence_has_left_rounded_down():
    assert winch_command(0.05, 0.0, NOW) == m.Winch(0.05)             # no deadline: no hold
    assert winch_command(0.05, NOW + 0.0457, NOW) == m.Winch(0.05, 0.045)
    assert winch_command(0.05, NOW + 1000.0, NOW) == m.Winch(0.05, 65.535)   # the wire's most
    assert winch_command(-0.02, NOW + 0.03, NOW) == m.Winch(-0.02, 0.03)


@pytest.mark.parametrize('late', [0.0, 0.0005, 0.2])
def test_a_command_whose_evidence_ran_out_is_sent_as_a_brake(late):
    # Less than the MCU's 1 ms resolution left, or past: nothing may move on it.
    assert winch_command(0.05, NOW + 0.0009 - late, NOW) == m.Winch(0.0)


def test_a_held_winch_command_is_never_resent():
    t = {'now': 0.0}
    core = BridgeCore(BridgeConfig(ack_timeout=0.15), mono=lambda: t['now'],
                      wall=lambda: NOW + t['now'])
    core.on_connection(True)
    held = FrameDecoder().feed(core.command(m.Winch(0.05, 0.04)))[0]
    t['now'] = 0.2                                    # not acked within ack_timeout
    resend, failed = core.due_retries()
    assert resend == []
    assert [(r.seq, r.result) for r in failed] == [(held.seq, None)]
    plain = FrameDecoder().feed(core.command(m.Winch(0.0)))[0]
    t['now'] = 0.4
    resend, failed = core.due_retries()
    assert [FrameDecoder().feed(f)[0].seq for f in resend] == [plain.seq] and failed == []
