"""Which unacknowledged commands the bridge resends (src/minirquad_driver/PROTOCOL.md, "seq"):
a command whose ack did not come within ack_timeout is resent with its own seq, unless a newer
command of its channel (legs, winch, e-stop) went out since. The MCU executes a resent frame
again unless it is the last one it received (tests/sim/test_mcu_contract.py), so a resent
older command would undo the newer one."""
from __future__ import annotations

from minirquad_driver.bridge import BridgeConfig, BridgeCore
from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

NOW = 1.7e9
STAND = m.SetGait(m.GaitKind.STAND, down=0.0)


def _core():
    t = {'now': 0.0}
    core = BridgeCore(BridgeConfig(ack_timeout=0.15, max_retries=3), mono=lambda: t['now'],
                      wall=lambda: NOW + t['now'])
    core.on_connection(True)
    return core, t


def _seq(frame: bytes) -> int:
    return FrameDecoder().feed(frame)[0].seq


def _seqs(frames) -> list[int]:
    return [_seq(f) for f in frames]


def test_a_stand_lost_before_a_burrow_is_not_resent_after_it():
    core, t = _core()
    core.command(STAND)
    burrow = _seq(core.command(m.Burrow(m.BurrowMode.DH)))
    t['now'] = 0.2                                    # neither acked within ack_timeout
    resend, failed = core.due_retries()
    assert _seqs(resend) == [burrow]
    assert failed == []                  # replaced, not failed: no "no ack" warning
    assert core.counters.commands_superseded == 1
    assert core.counters.command_retries == 1


def test_leg_targets_streamed_are_resent_only_the_newest():
    core, t = _core()
    frames = [core.command(m.SetLegs((0.1 * k, 0.0, 0.0, 0.0))) for k in range(5)]
    t['now'] = 0.2
    resend, _ = core.due_retries()
    assert _seqs(resend) == [_seq(frames[-1])]


def test_commands_of_other_channels_are_all_resent():
    core, t = _core()
    sent = [core.command(msg) for msg in (m.Winch(0.0), m.Burrow(m.BurrowMode.SH),
                                          m.EStop(False))]
    t['now'] = 0.2
    resend, failed = core.due_retries()
    assert sorted(_seqs(resend)) == sorted(_seqs(sent)) and failed == []


def test_a_late_ack_of_a_replaced_command_is_still_matched():
    core, t = _core()
    stand = _seq(core.command(STAND))
    core.command(m.Burrow(m.BurrowMode.DH))
    t['now'] = 0.05
    ack = encode_frame(m.Ack(stand, m.MsgType.SET_GAIT, m.AckResult.OK), 0, 50)
    core.on_bytes(ack, NOW + t['now'])
    assert core.counters.commands_acked == 1 and core.counters.unmatched_acks == 0


def test_awaiting_ack_asks_about_the_newest_command_of_a_type():
    core, t = _core()
    first = _seq(core.command(m.Winch(0.05)))
    second = _seq(core.command(m.Winch(0.0)))
    assert core.awaiting_ack(m.MsgType.WINCH)
    core.on_bytes(encode_frame(m.Ack(second, m.MsgType.WINCH, m.AckResult.OK), 0, 10),
                  NOW + t['now'])
    # The brake is acknowledged: the speed it replaced has no say any more.
    assert not core.awaiting_ack(m.MsgType.WINCH)
    t['now'] = 0.2
    resend, failed = core.due_retries()
    assert resend == [] and failed == [] and first != second
