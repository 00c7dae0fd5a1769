"""Consistent Overhead Byte Stuffing (Cheshire and Baker, 1999).

``encode`` turns any byte string into one without 0x00 bytes (overhead: one byte per 254
bytes of input, plus one), so 0x00 can delimit frames on the wire. ``decode`` is the strict
inverse and raises ``CobsError`` on anything ``encode`` cannot have produced.
"""
from __future__ import annotations


class CobsError(ValueError):
    """The input is not a valid COBS encoding."""


def encode(data: bytes) -> bytes:
    """COBS-encode ``data``; the result contains no 0x00 byte."""
    out = bytearray()
    block = bytearray()
    closed_full = False
    for byte in data:
        closed_full = False
        if byte == 0:
            out.append(len(block) + 1)
            out += block
            block.clear()
        else:
            block.append(byte)
            # A full block of 254 non-zero bytes is closed with code 0xFF, which implies no zero.
            if len(block) == 254:
                out.append(0xFF)
                out += block
                block.clear()
                closed_full = True
    # Canonical form (as in the paper's examples): input ending exactly on a full block
    # needs no trailing empty block.
    if not closed_full:
        out.append(len(block) + 1)
        out += block
    return bytes(out)


def decode(data: bytes) -> bytes:
    """Inverse of ``encode``. Raises ``CobsError`` on a zero byte or a code past the end.

    It also accepts the non-canonical trailing empty block after a full 0xFF block; the
    CRC above this layer is what rejects damaged frames.
    """
    out = bytearray()
    i = 0
    n = len(data)
    if n == 0:
        raise CobsError('empty COBS block')
    while i < n:
        code = data[i]
        if code == 0:
            raise CobsError(f'zero byte at {i}')
        end = i + code
        if end > n:
            raise CobsError(f'code {code} at {i} runs past the end ({n})')
        block = data[i + 1:end]
        if 0 in block:
            raise CobsError('zero byte inside a block')
        out += block
        i = end
        # A code below 0xFF stands for "block, then a zero" unless it ends the input.
        if code < 0xFF and i < n:
            out.append(0)
    return bytes(out)
