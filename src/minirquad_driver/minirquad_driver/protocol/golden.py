"""Golden frames: the bytes on the wire for every message type, written by this codec.

The firmware (C++) and this package implement the same protocol. To keep them one protocol,
a committed text file lists frames as field values and wire bytes; both codecs' own tests
check it byte for byte. Regenerate it (after a deliberate protocol change only) with

    python -m minirquad_driver.protocol.golden \
        --write src/minirquad_driver/firmware/tests/golden_frames.txt

Line formats (whitespace-separated; ``#`` starts a comment line):

    frame <name> <expect> <type> <seq> <t_ms> <nfields> <field>... <payload_hex> <wire_hex>
    stream <name> <wire_hex> <frames> <cobs> <crc> <short> <version> <unknown> <payload>
           <range> <overflow>          (one line)

``expect`` is ``ok`` (the frame decodes to these fields and encoding the fields gives these
bytes), ``payload`` or ``range`` (an intact frame whose payload the receiver must drop and
count in that counter). Fields are the payload's wire integers in struct order (a LOG's are
its bytes); ``nfields`` is -1 when the payload has the wrong size and so has no fields.
A ``stream`` row is a byte stream with the decoder counters it must leave behind.
"""
from __future__ import annotations

import argparse
import struct
import sys
from collections.abc import Iterator
from dataclasses import dataclass

from rftgls_conventions.safe_write import write_text

from . import cobs
from . import messages as m
from .codec import CRC, HEADER, FrameDecoder, encode_frame
from .crc import crc16_ccitt_false

# Struct layout of each payload, as in messages.py (LOG: any bytes; empty: no payload).
LAYOUTS: dict[int, str] = {
    m.MsgType.TELEMETRY: '<4i4hihiiiBH', m.MsgType.POWER: '<HhhHH', m.MsgType.ACK: '<BBB',
    m.MsgType.RESET_NOTICE: '<BHBHH', m.MsgType.INFO: '<BHBHH', m.MsgType.ERROR: '<BH',
    m.MsgType.HEARTBEAT: '<', m.MsgType.GET_INFO: '<', m.MsgType.SET_LEGS: '<B4i',
    m.MsgType.SET_GAIT: '<BHHii4Hb', m.MsgType.BURROW: '<B', m.MsgType.WINCH: '<iH',
    m.MsgType.ESTOP: '<B',
}
COUNTERS = ('frames', 'cobs_errors', 'crc_errors', 'short_frames', 'version_errors',
            'unknown_types', 'payload_errors', 'range_errors', 'overflows')
PI_URAD = 3141593
I32_MIN, I32_MAX = -2**31, 2**31 - 1


@dataclass(frozen=True)
class FrameCase:
    name: str
    expect: str            # ok | payload | range
    type: int
    seq: int
    t_ms: int
    fields: tuple[int, ...] | None   # None: wrong payload size
    payload: bytes
    wire: bytes


@dataclass(frozen=True)
class StreamCase:
    name: str
    wire: bytes
    counters: tuple[int, ...]      # in COUNTERS order


def raw_frame(mtype: int, seq: int, t_ms: int, payload: bytes,
              version: int = m.PROTOCOL_VERSION) -> bytes:
    """Wire bytes of a frame built from raw payload bytes (no field validation)."""
    body = HEADER.pack(version, mtype, seq, t_ms) + payload
    body += CRC.pack(crc16_ccitt_false(body))
    return b'\x00' + cobs.encode(body) + b'\x00'


def _pack(mtype: int, fields) -> bytes:
    if mtype == m.MsgType.LOG:
        return bytes(fields)
    return struct.pack(LAYOUTS[mtype], *fields)


def _ok(name, mtype, fields, seq=0, t_ms=0) -> FrameCase:
    """A valid frame: the wire bytes come from the typed message through encode_frame."""
    payload = _pack(mtype, fields)
    message = m.MESSAGE_CLASSES[mtype].unpack(payload)
    if message.pack() != payload:
        raise ValueError(f'{name}: the payload does not survive a round trip')
    wire = encode_frame(message, seq, t_ms)
    return FrameCase(name, 'ok', mtype, seq, t_ms, tuple(fields), payload, wire)


def _bad(name, expect, mtype, fields=None, payload=None, seq=0, t_ms=0) -> FrameCase:
    payload = _pack(mtype, fields) if payload is None else payload
    return FrameCase(name, expect, mtype, seq, t_ms,
                     None if fields is None else tuple(fields), payload,
                     raw_frame(mtype, seq, t_ms, payload))


def frame_cases() -> Iterator[FrameCase]:
    T = m.MsgType
    tel0 = [0] * 15
    tel_max = [PI_URAD, -PI_URAD, PI_URAD, -PI_URAD, 32767, -32767, 32767, -32767, PI_URAD,
               -32767, I32_MAX, -I32_MAX, I32_MAX, int(m.Mode.WATCHDOG), m.ALL_FLAGS]
    yield _ok('telemetry.zero', T.TELEMETRY, tel0)
    yield _ok('telemetry.max', T.TELEMETRY, tel_max, seq=255, t_ms=0xFFFFFFFF)
    yield _ok('telemetry.min', T.TELEMETRY,
              [-PI_URAD, PI_URAD, -PI_URAD, PI_URAD, -32767, 32767, -32767, 32767, -PI_URAD,
               32767, -I32_MAX, I32_MAX, -I32_MAX, int(m.Mode.IDLE), 0], seq=1, t_ms=1)
    yield _ok('telemetry.walking', T.TELEMETRY,
              [123457, -500000, 2000000, -1, 1001, -250, 0, 12, 87267, -3, 2942, 100000,
               -5000, int(m.Mode.WALKING), int(m.Flag.SLED_MOVING | m.Flag.ANCHOR_SLIPPING)],
              seq=17, t_ms=123456)
    for mode in m.Mode:
        yield _ok(f'telemetry.mode_{mode.name.lower()}', T.TELEMETRY,
                  tel0[:13] + [int(mode), 0], seq=int(mode), t_ms=1000 * int(mode))
    for flag in m.Flag:
        yield _ok(f'telemetry.flag_{flag.name.lower()}', T.TELEMETRY,
                  tel0[:14] + [int(flag)], seq=100 + flag.bit_length())
    for i in range(5):     # each angle field just outside (-pi, pi]: a size-valid payload
        for sign in (1, -1):
            f = list(tel0)
            f[i if i < 4 else 8] = sign * (PI_URAD + 1)
            yield _bad(f'telemetry.angle{i}_{"above" if sign > 0 else "below"}_pi',
                       'payload', T.TELEMETRY, f)
    yield _bad('telemetry.mode_7', 'range', T.TELEMETRY, tel0[:13] + [7, 0])
    yield _bad('telemetry.mode_255', 'range', T.TELEMETRY, tel0[:13] + [255, 0])
    yield _bad('telemetry.flag_0x80', 'range', T.TELEMETRY, tel0[:14] + [0x80])
    yield _bad('telemetry.flag_0x8000', 'range', T.TELEMETRY, tel0[:14] + [0x8000])
    # Both an angle and the mode out of range: the angle is checked first (payload).
    yield _bad('telemetry.angle_and_mode', 'payload', T.TELEMETRY,
               [PI_URAD + 1] + tel0[1:13] + [9, 0])
    yield _bad('telemetry.short', 'payload', T.TELEMETRY, payload=bytes(44))
    yield _bad('telemetry.long', 'payload', T.TELEMETRY, payload=bytes(46))

    yield _ok('power.zero', T.POWER, [0, 0, 0, 0, 0])
    yield _ok('power.adafruit_32v_2a', T.POWER, [(1850 << 3) | 2, 1234, 1234, 456, 4096],
              seq=3, t_ms=20)
    yield _ok('power.extremes', T.POWER, [0xFFFF, -32768, 32767, 0xFFFF, 0xFFFF])
    yield _ok('power.negative', T.POWER, [(1849 << 3) | 3, -32000, -32768, 0, 0])
    yield _bad('power.short', 'payload', T.POWER, payload=bytes(9))
    yield _bad('power.long', 'payload', T.POWER, payload=bytes(11))

    for t in sorted(m.HOST_TYPES):
        yield _ok(f'ack.type_0x{t:02x}', T.ACK, [t & 0xFF, t, 0], seq=t)
    for r in m.AckResult:
        yield _ok(f'ack.result_{r.name.lower()}', T.ACK, [255, T.WINCH, int(r)])
    for t in (0x00, 0x01, 0x07, 0x0F, 0x17, 0xFF):
        yield _bad(f'ack.acked_type_0x{t:02x}', 'range', T.ACK, [0, t, 0])
    yield _bad('ack.result_5', 'range', T.ACK, [0, T.HEARTBEAT, 5])
    yield _bad('ack.result_255', 'range', T.ACK, [0, T.HEARTBEAT, 255])
    yield _bad('ack.short', 'payload', T.ACK, payload=b'\x01\x10')
    yield _bad('ack.long', 'payload', T.ACK, payload=b'\x01\x10\x00\x00')

    v = m.PROTOCOL_VERSION
    for t, name in ((T.RESET_NOTICE, 'reset_notice'), (T.INFO, 'info')):
        for c in m.ResetCause:
            yield _ok(f'{name}.cause_{c.name.lower()}', t, [v, 100, int(c), 100, 50])
        yield _ok(f'{name}.max', t, [v, 0xFFFF, 255, 0xFFFF, 0xFFFF])
        yield _ok(f'{name}.zero_rates', t, [v, 0, 0, 0, 0])
        for other in (0, v - 1, v + 1, 255):
            yield _bad(f'{name}.protocol_{other}', 'range', t, [other, 100, 0, 100, 50])
        for c in (4, 254):
            yield _bad(f'{name}.cause_{c}', 'range', t, [v, 100, c, 100, 50])
        yield _bad(f'{name}.short', 'payload', t, payload=bytes([v, 0, 0, 0, 0, 0, 0]))

    for code in m.ErrorCode:
        yield _ok(f'error.{code.name.lower()}', T.ERROR, [int(code), 0xFFFF if code == 6 else 7])
    for code in (0, 9, 255):
        yield _bad(f'error.code_{code}', 'range', T.ERROR, [code, 0])
    yield _bad('error.short', 'payload', T.ERROR, payload=b'\x01\x00')

    yield _ok('log.empty', T.LOG, [])
    yield _ok('log.hello', T.LOG, list(b'MiniRQuad firmware 100'))
    yield _ok('log.utf8', T.LOG, list('winch \u00b5m/s'.encode()))
    yield _ok('log.200', T.LOG, [0x41 + i % 26 for i in range(200)])
    yield _bad('log.201', 'payload', T.LOG, payload=b'x' * 201)

    yield _ok('heartbeat', T.HEARTBEAT, [], seq=42, t_ms=99)
    yield _ok('heartbeat.wrap', T.HEARTBEAT, [], seq=255, t_ms=0xFFFFFFFF)
    yield _bad('heartbeat.payload', 'payload', T.HEARTBEAT, payload=b'\x00')
    yield _ok('get_info', T.GET_INFO, [], seq=7)
    yield _bad('get_info.payload', 'payload', T.GET_INFO, payload=b'\x01\x02')

    yield _ok('set_legs.zero', T.SET_LEGS, [0x0F, 0, 0, 0, 0])
    yield _ok('set_legs.edges', T.SET_LEGS, [0x0F, PI_URAD, -PI_URAD, 1, -1], seq=9)
    yield _ok('set_legs.mask0', T.SET_LEGS, [0, 5, 6, 7, 8])
    yield _ok('set_legs.mask5', T.SET_LEGS, [5, -1308997, 0, 523599, 0])
    yield _bad('set_legs.mask16', 'payload', T.SET_LEGS, [16, 0, 0, 0, 0])
    for i in range(4):
        f = [0x0F, 0, 0, 0, 0]
        f[1 + i] = PI_URAD + 1 if i % 2 == 0 else -PI_URAD - 1
        yield _bad(f'set_legs.target{i}_out', 'payload', T.SET_LEGS, f)
    yield _bad('set_legs.short', 'payload', T.SET_LEGS, payload=bytes(16))

    walk = [1, 2000, 4200, 698132, 349066, 0, 32768, 32768, 0, 1]
    yield _ok('set_gait.walk', T.SET_GAIT, walk, seq=200, t_ms=5000)
    yield _ok('set_gait.stand', T.SET_GAIT, [0, 1000, 5000, 700000, 0, 0, 32768, 32768, 0, 1])
    yield _ok('set_gait.min', T.SET_GAIT, [1, 50, 1, 1, -PI_URAD, 0, 0, 0, 0, -1])
    yield _ok('set_gait.max', T.SET_GAIT,
              [1, 0xFFFF, 9999, 6283184, PI_URAD, 0xFFFF, 0xFFFF, 0xFFFF, 0xFFFF, 1])
    for idx, value, name in ((0, 2, 'kind_2'), (1, 49, 'period_49'), (1, 0, 'period_0'),
                             (2, 0, 'duty_0'), (2, 10000, 'duty_1'), (3, 0, 'sweep_0'),
                             (3, 6283185, 'sweep_2pi'), (3, -1, 'sweep_negative'),
                             (4, PI_URAD + 1, 'down_above_pi'),
                             (4, -PI_URAD - 1, 'down_below_pi'),
                             (9, 0, 'direction_0'), (9, 2, 'direction_2'),
                             (9, -128, 'direction_min')):
        f = list(walk)
        f[idx] = value
        yield _bad(f'set_gait.{name}', 'payload', T.SET_GAIT, f)
    yield _bad('set_gait.long', 'payload', T.SET_GAIT, payload=bytes(27))

    for b in m.BurrowMode:
        yield _ok(f'burrow.{b.name.lower()}', T.BURROW, [int(b)], seq=int(b))
    yield _bad('burrow.mode_4', 'payload', T.BURROW, [4])
    yield _bad('burrow.mode_255', 'payload', T.BURROW, [255])
    yield _bad('burrow.empty', 'payload', T.BURROW, payload=b'')

    for v in (0, 1, -1, 20000, -50000, 1000000, -1000000):
        yield _ok(f'winch.{v}', T.WINCH, [v, 0])
    for hold in (1, 60, 65535):
        yield _ok(f'winch.50000_hold_{hold}ms', T.WINCH, [50000, hold])
    yield _bad('winch.above_1ms', 'payload', T.WINCH, [1000001, 0])
    yield _bad('winch.below_1ms', 'payload', T.WINCH, [-1000001, 0])
    yield _bad('winch.int_min', 'payload', T.WINCH, [I32_MIN, 0])
    yield _bad('winch.short', 'payload', T.WINCH, payload=b'\x01\x00\x00')
    yield _bad('winch.without_hold', 'payload', T.WINCH, payload=b'\x50\xc3\x00\x00')

    yield _ok('estop.engage', T.ESTOP, [1])
    yield _ok('estop.release', T.ESTOP, [0])
    yield _bad('estop.2', 'payload', T.ESTOP, [2])
    yield _bad('estop.long', 'payload', T.ESTOP, payload=b'\x01\x01')


def _counters(wire: bytes) -> tuple[int, ...]:
    dec = FrameDecoder()
    dec.feed(wire)
    return tuple(getattr(dec.stats, k) for k in COUNTERS)


def stream_cases() -> Iterator[StreamCase]:
    hb = encode_frame(m.Heartbeat(), 1, 2)
    body = HEADER.pack(1, m.MsgType.HEARTBEAT, 1, 2)
    crc = crc16_ccitt_false(body)

    def stuffed(b: bytes) -> bytes:
        return b'\x00' + cobs.encode(b) + b'\x00'

    streams = {
        'empty_segments': b'\x00' * 5,
        'heartbeat_alone': hb,
        'heartbeat_no_leading_zero': hb[1:],
        'cobs_code_past_end': b'\x00\x05\x01\x00',
        'cobs_code_past_end_then_frame': b'\x00\x05\x01' + hb,
        'short_body': stuffed(body[:-1] + b'\x00'),
        'short_body_1': stuffed(b'\x01'),
        'crc_off_by_one': stuffed(body + CRC.pack(crc ^ 0x0001)),
        'crc_byte_swapped': stuffed(body + struct.pack('>H', crc)),
        'crc_missing': stuffed(body + b'\x00\x00'),
        'version_0': raw_frame(m.MsgType.HEARTBEAT, 0, 0, b'', version=0),
        'version_1': raw_frame(m.MsgType.HEARTBEAT, 0, 0, b'', version=1),   # before WINCH's hold
        'version_3': raw_frame(m.MsgType.HEARTBEAT, 0, 0, b'', version=3),
        'unknown_type_0x00': raw_frame(0x00, 0, 0, b''),
        'unknown_type_0x08': raw_frame(0x08, 0, 0, b''),
        'unknown_type_0x17': raw_frame(0x17, 0, 0, b''),
        'unknown_type_0xff': raw_frame(0xFF, 0, 0, b''),
        # 258 stuffed bytes is the longest segment decoded (here 257 zeros, which the CRC
        # rejects); 259 is an overflow, dropped up to the next delimiter.
        'segment_258': b'\x00' + b'\x01' * 258 + b'\x00',
        'segment_259_overflow': b'\x00' + b'\x01' * 259 + b'\x00' + hb,
        'overflow_long_junk': b'\x00' + b'\x7f' * 1000 + hb,
        'junk_before_frame': b'\x13\x37\xff\xfe' + hb,
        'cut_frame_then_frame': hb[:6] + hb,
        'two_frames_one_delimiter': hb + hb[1:],
        # A full 254-byte block (code 0xFF) followed by the non-canonical empty block.
        'cobs_ff_block': b'\x00\xff' + bytes(range(1, 255)) + b'\x01\x00',
    }
    for name, wire in streams.items():
        yield StreamCase(name, wire, _counters(wire))


def render() -> str:
    lines = [
        '# MiniRQuad serial protocol v1: golden frames written by the Python codec',
        '# (minirquad_driver/protocol/golden.py explains the format). Regenerate with:',
        '#   python -m minirquad_driver.protocol.golden --write '
        'src/minirquad_driver/firmware/tests/golden_frames.txt',
        '# stream counters: ' + ' '.join(COUNTERS),
    ]
    for c in frame_cases():
        fields = ['-1'] if c.fields is None else [str(len(c.fields)), *map(str, c.fields)]
        lines.append(' '.join(['frame', c.name, c.expect, str(c.type), str(c.seq),
                               str(c.t_ms), *fields, c.payload.hex() or '-', c.wire.hex()]))
    for s in stream_cases():
        lines.append(' '.join(['stream', s.name, s.wire.hex(), *map(str, s.counters)]))
    return '\n'.join(lines) + '\n'


def parse(text: str) -> tuple[list[FrameCase], list[StreamCase]]:
    """Read a golden file back (the inverse of ``render``)."""
    frames, streams = [], []
    for line in text.splitlines():
        if not line.strip() or line.startswith('#'):
            continue
        tok = line.split()
        if tok[0] == 'frame':
            n = int(tok[6])
            fields = None if n < 0 else tuple(int(x) for x in tok[7:7 + n])
            rest = tok[7 + max(n, 0):]
            payload = b'' if rest[0] == '-' else bytes.fromhex(rest[0])
            frames.append(FrameCase(tok[1], tok[2], int(tok[3]), int(tok[4]), int(tok[5]),
                                    fields, payload, bytes.fromhex(rest[1])))
        elif tok[0] == 'stream':
            streams.append(StreamCase(tok[1], bytes.fromhex(tok[2]),
                                      tuple(int(x) for x in tok[3:])))
        else:
            raise ValueError(f'unknown golden row {tok[0]!r}')
    return frames, streams


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog='python -m minirquad_driver.protocol.golden',
                                description=__doc__.split('\n\n')[0])
    p.add_argument('--write', metavar='FILE', help='write the golden file (default: stdout)')
    args = p.parse_args(argv)
    text = render()
    if args.write:
        write_text(args.write, text, encoding='ascii')   # atomic, never through a link
    else:
        sys.stdout.write(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
