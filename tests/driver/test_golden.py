"""Golden frames, Python side: the committed file is what this codec writes and reads.

The same file is checked byte for byte by the firmware's C++ codec
(tests/firmware/test_firmware.py runs its unit tests), so a change on either side that moves a
single wire byte fails one of the two.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from minirquad_driver.protocol import golden
from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

GOLDEN = (Path(__file__).resolve().parents[2] / 'src' / 'minirquad_driver' / 'firmware'
          / 'tests' / 'golden_frames.txt')
FRAMES, STREAMS = golden.parse(GOLDEN.read_text())


def test_committed_file_is_what_the_codec_writes():
    # After a deliberate protocol change: regenerate (command in the file's header).
    assert GOLDEN.read_text() == golden.render()


def test_golden_covers_every_message_type_and_every_check():
    types = {c.type for c in FRAMES if c.expect == 'ok'}
    assert types == set(m.MESSAGE_CLASSES)
    # Every type has a wrong-size row; every enum/flag field has a range row.
    assert {c.type for c in FRAMES if c.fields is None} == set(m.MESSAGE_CLASSES)
    assert {c.type for c in FRAMES if c.expect == 'range'} == {
        m.MsgType.TELEMETRY, m.MsgType.ACK, m.MsgType.RESET_NOTICE, m.MsgType.INFO,
        m.MsgType.ERROR}
    assert len({c.name for c in FRAMES}) == len(FRAMES)
    assert len(FRAMES) > 150 and len(STREAMS) >= 20


@pytest.mark.parametrize('case', FRAMES, ids=lambda c: c.name)
def test_golden_frame(case):
    dec = FrameDecoder()
    got = dec.feed(case.wire)
    if case.expect == 'ok':
        assert len(got) == 1
        f = got[0]
        assert (f.seq, f.t_mcu_ms, int(f.message.TYPE)) == (case.seq, case.t_ms, case.type)
        assert f.message == m.MESSAGE_CLASSES[case.type].unpack(case.payload)
        # Fields -> bytes: the typed message encodes to exactly the golden wire bytes.
        assert encode_frame(f.message, case.seq, case.t_ms) == case.wire
        assert golden._pack(case.type, case.fields) == case.payload
    else:
        assert got == []
        counter = {'payload': 'payload_errors', 'range': 'range_errors'}[case.expect]
        assert getattr(dec.stats, counter) == 1 and dec.stats.rejected == 1


@pytest.mark.parametrize('case', STREAMS, ids=lambda c: c.name)
def test_golden_stream(case):
    dec = FrameDecoder()
    frames = []
    for i in range(len(case.wire)):      # byte by byte: chunking must not matter
        frames += dec.feed(case.wire[i:i + 1])
    assert tuple(getattr(dec.stats, k) for k in golden.COUNTERS) == case.counters
    assert len(frames) == case.counters[0]
