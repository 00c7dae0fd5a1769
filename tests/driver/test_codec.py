"""Frame encoder/decoder properties: round trip, garbage, truncation, bit flips, resync."""
import dataclasses
import math

from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import any_message

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

stamp = st.integers(0, 2**32 - 1)
seq = st.integers(0, 255)


def _close(a, b, tol):
    """Field-by-field comparison allowing the fixed-point rounding of each float field."""
    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, tuple):
            assert all(abs(p - q) <= tol for p, q in zip(x, y)), f.name
        elif isinstance(x, float):
            assert abs(x - y) <= tol, f.name
        else:
            assert x == y, f.name


@given(any_message, seq, stamp)
def test_every_message_round_trips(msg, s, t):
    frames = FrameDecoder().feed(encode_frame(msg, s, t))
    assert len(frames) == 1
    f = frames[0]
    assert (f.seq, f.t_mcu_ms, f.version) == (s, t, m.PROTOCOL_VERSION)
    # Rounding bound: half the coarsest LSB used by a float field (1 ms period -> 5e-4).
    _close(msg, f.message, 5e-4 + 1e-12)
    # A decoded message is on the wire grid, so it round-trips exactly.
    again = FrameDecoder().feed(encode_frame(f.message, s, t))[0].message
    assert again == f.message


def test_wire_rounding_of_telemetry_units():
    tel = m.Telemetry(leg_angles=(0.1234567, -0.5, math.pi, -math.pi + 1e-6),
                      leg_velocities=(1.0006, 0, 0, 0), pitch=0.0872665, pitch_rate=0.0,
                      tension=2.94213, spool_position=0.1, spool_velocity=-0.005)
    got = FrameDecoder().feed(encode_frame(tel, 1, 2))[0].message
    assert got.leg_angles[0] == 0.123457           # 1 urad grid
    assert got.leg_velocities[0] == 1.001          # 1 mrad/s grid
    assert got.tension == 2.942                    # 1 mN grid
    assert got.spool_velocity == -0.005


def test_out_of_range_and_nan_are_refused_at_encode():
    import pytest
    with pytest.raises(ValueError):
        m.Winch(float('nan')).pack()
    with pytest.raises(ValueError):
        m.Winch(2.0).pack()
    with pytest.raises(ValueError):
        m.SetGait(kind=m.GaitKind.CLOCK, duty=1.0).pack()


@given(st.binary(max_size=2000))
def test_garbage_never_raises_and_never_yields(data):
    dec = FrameDecoder()
    # Random bytes pass COBS, CRC, version, type and size checks with odds ~1e-7 per segment.
    assert dec.feed(data) == []


@settings(max_examples=200)
@given(st.lists(st.tuples(any_message, seq, stamp), min_size=1, max_size=8),
       st.lists(st.binary(max_size=60), min_size=1, max_size=8),
       st.integers(1, 64))
def test_resync_after_garbage_in_any_chunking(items, junk, chunk):
    """Junk between frames (with or without zeros) costs nothing, since every frame also
    starts with a delimiter; the result does not depend on how reads chop the stream."""
    wire = b''
    frames = [encode_frame(msg, s, t) for msg, s, t in items]
    for i, fr in enumerate(frames):
        wire += junk[i % len(junk)] + fr
    dec = FrameDecoder()
    got = []
    for i in range(0, len(wire), chunk):
        got += dec.feed(wire[i:i + chunk])
    want = [FrameDecoder().feed(fr)[0] for fr in frames]
    assert got == want


@settings(max_examples=300)
@given(st.lists(st.tuples(any_message, seq, stamp), min_size=1, max_size=6), st.data())
def test_truncation_and_bit_flips_never_yield_a_damaged_frame(items, data):
    """Damage some frames (cut short, or 1-3 distinct bits flipped on the wire); every yielded
    frame must be one of the undamaged originals, and every intact frame must come through.

    A flip in a data byte is a 1-3 bit error of the unstuffed frame, which CRC-16/CCITT always
    detects at these lengths; a flip in a COBS code byte scrambles the layout instead, which
    CRC-16 plus the version, type and payload-size checks pass with odds far below 2**-16.
    """
    frames = [encode_frame(msg, s, t) for msg, s, t in items]
    originals = [FrameDecoder().feed(fr)[0] for fr in frames]
    wire = b''
    intact = []
    for fr, orig in zip(frames, originals):
        action = data.draw(st.sampled_from(['keep', 'cut', 'flip']))
        if action == 'keep':
            wire += fr
            intact.append(orig)
        elif action == 'cut':
            # Keep at most all but the last COBS byte (and lose the closing delimiter): a
            # frame cut off by a reset. Cutting only the delimiter is no damage at all,
            # since the next frame's leading 0x00 closes the frame.
            n = data.draw(st.integers(1, len(fr) - 2))
            wire += fr[:n]
        else:
            buf = bytearray(fr)
            # Distinct bits, so two flips never cancel out.
            bits = data.draw(st.sets(st.tuples(st.integers(1, len(buf) - 2),  # keep delimiters
                                               st.integers(0, 7)), min_size=1, max_size=3))
            for pos, bit in bits:
                buf[pos] ^= 1 << bit
            wire += bytes(buf)
    got = FrameDecoder().feed(wire)
    for f in got:
        assert f in originals
    assert [f for f in got if f in intact] == intact


def test_decoder_counts_each_kind_of_damage():
    good = encode_frame(m.Heartbeat(), 7, 1000)
    dec = FrameDecoder()
    bad_crc = bytearray(good)
    bad_crc[3] ^= 0x01
    frames = dec.feed(bytes(bad_crc) + b'\x00\x05\x01' + good + b'\x01' * 400 + good)
    assert len(frames) == 2
    assert dec.stats.crc_errors == 1
    assert dec.stats.cobs_errors == 1       # code 5 runs past the end of "05 01"
    assert dec.stats.overflows == 1


def test_decoder_rejects_unknown_version_and_type():
    dec = FrameDecoder()
    assert dec.stats.other_version is None
    assert dec.feed(encode_frame(m.Heartbeat(), 0, 0, version=m.PROTOCOL_VERSION + 1)) == []
    assert dec.stats.version_errors == 1
    assert dec.stats.other_version == m.PROTOCOL_VERSION + 1     # what the other end speaks
    from minirquad_driver.protocol import cobs
    from minirquad_driver.protocol.crc import crc16_ccitt_false
    body = bytes([m.PROTOCOL_VERSION, 0x7F, 0, 0, 0, 0, 0])
    body += crc16_ccitt_false(body).to_bytes(2, 'little')
    assert dec.feed(b'\x00' + cobs.encode(body) + b'\x00') == []
    assert dec.stats.unknown_types == 1
