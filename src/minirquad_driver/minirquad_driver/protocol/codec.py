"""Frames on the wire, and a decoder that survives any byte stream.

Frame before stuffing (all little-endian)::

    version:u8 | type:u8 | seq:u8 | t_mcu_ms:u32 | payload | crc16:u16

The CRC-16/CCITT-FALSE covers every byte before it. The frame is COBS-encoded and sent as
``0x00 <cobs> 0x00``: the leading zero costs one byte but stops junk without a zero (a boot
banner, half a frame cut by a reset) from merging with the next good frame.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

from . import cobs
from .crc import crc16_ccitt_false
from .messages import MESSAGE_CLASSES, PROTOCOL_VERSION, FieldRangeError, Message

HEADER = struct.Struct('<BBBI')
CRC = struct.Struct('<H')
DELIMITER = b'\x00'
#: Longest unstuffed frame we accept (header + largest payload + CRC, with margin).
MAX_FRAME = 256
#: A COBS body can be at most this long for MAX_FRAME bytes; longer runs are junk.
MAX_ENCODED = MAX_FRAME + MAX_FRAME // 254 + 1


@dataclass(frozen=True)
class Frame:
    """One decoded frame. t_mcu_ms is the sender's uint32 millisecond clock (wraps)."""

    seq: int
    t_mcu_ms: int
    message: Message
    version: int = PROTOCOL_VERSION


def encode_frame(message: Message, seq: int, t_mcu_ms: int,
                 version: int = PROTOCOL_VERSION) -> bytes:
    """Bytes to write for ``message``: 0x00, COBS(header, payload, CRC), 0x00."""
    body = HEADER.pack(version, int(message.TYPE), seq & 0xFF, t_mcu_ms & 0xFFFFFFFF)
    body += message.pack()
    body += CRC.pack(crc16_ccitt_false(body))
    return DELIMITER + cobs.encode(body) + DELIMITER


@dataclass
class DecoderStats:
    """Counts of what the decoder saw; every dropped segment lands in exactly one counter."""

    frames: int = 0
    bytes_in: int = 0
    cobs_errors: int = 0
    crc_errors: int = 0
    short_frames: int = 0        # too short to hold header and CRC
    version_errors: int = 0
    unknown_types: int = 0
    payload_errors: int = 0      # right CRC, but the payload does not decode (size, value)
    range_errors: int = 0        # right size, but an enum/flag field the protocol lacks
    overflows: int = 0           # no delimiter within MAX_ENCODED bytes
    # The version byte of the last intact frame (right CRC) of another protocol version: what
    # the other end speaks when none of its frames gets through (None: none seen).
    other_version: int | None = None

    @property
    def rejected(self) -> int:
        return (self.cobs_errors + self.crc_errors + self.short_frames + self.version_errors
                + self.unknown_types + self.payload_errors + self.range_errors
                + self.overflows)

    @property
    def protocol_rejects(self) -> int:
        """Intact frames (right CRC) refused for a value this protocol does not define:
        another version, an unknown type, an out-of-range enum or flag field."""
        return self.version_errors + self.unknown_types + self.range_errors


@dataclass
class FrameDecoder:
    """Incremental decoder: feed it any chunks of bytes, get back the valid frames.

    It never raises on input data. A frame is yielded only if COBS decoding succeeds, the CRC
    matches, the version is known and the payload unpacks for its type. After garbage it
    resynchronises at the next 0x00.
    """

    stats: DecoderStats = field(default_factory=DecoderStats)
    _buf: bytearray = field(default_factory=bytearray)
    _skipping: bool = False   # inside an overlong segment: drop bytes until the next 0x00

    def reset(self) -> None:
        """Forget a partial frame (after a reconnect the old bytes belong to nothing)."""
        self._buf.clear()
        self._skipping = False

    def feed(self, data: bytes) -> list[Frame]:
        frames: list[Frame] = []
        self.stats.bytes_in += len(data)
        start = 0
        while True:
            end = data.find(0, start)
            chunk = data[start:] if end < 0 else data[start:end]
            if not self._skipping:
                self._buf += chunk
                if len(self._buf) > MAX_ENCODED:
                    self.stats.overflows += 1
                    self._buf.clear()
                    self._skipping = True
            if end < 0:
                return frames
            if self._skipping:
                self._skipping = False
            elif self._buf:
                frame = self._decode_segment(bytes(self._buf))
                if frame is not None:
                    frames.append(frame)
            self._buf.clear()
            start = end + 1

    def _decode_segment(self, segment: bytes) -> Frame | None:
        try:
            body = cobs.decode(segment)
        except cobs.CobsError:
            self.stats.cobs_errors += 1
            return None
        if len(body) < HEADER.size + CRC.size:
            self.stats.short_frames += 1
            return None
        (crc,) = CRC.unpack_from(body, len(body) - CRC.size)
        if crc16_ccitt_false(body[:-CRC.size]) != crc:
            self.stats.crc_errors += 1
            return None
        version, mtype, seq, t_ms = HEADER.unpack_from(body)
        if version != PROTOCOL_VERSION:
            self.stats.version_errors += 1
            self.stats.other_version = version
            return None
        cls = MESSAGE_CLASSES.get(mtype)
        if cls is None:
            self.stats.unknown_types += 1
            return None
        try:
            message = cls.unpack(body[HEADER.size:-CRC.size])
        except FieldRangeError:
            self.stats.range_errors += 1
            return None
        except (ValueError, struct.error, UnicodeDecodeError):
            self.stats.payload_errors += 1
            return None
        self.stats.frames += 1
        return Frame(seq=seq, t_mcu_ms=t_ms, message=message, version=version)
