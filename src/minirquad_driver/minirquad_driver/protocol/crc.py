"""CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected, no final xor).

Python's ``binascii.crc_hqx`` is exactly this CRC when started at 0xFFFF; the firmware side
is a ten-line bitwise loop. Check value for b"123456789" is 0x29B1.
"""
from __future__ import annotations

import binascii

CRC_INIT = 0xFFFF


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` as an int in [0, 0xFFFF]."""
    return binascii.crc_hqx(data, CRC_INIT)
