"""CRC-16/CCITT-FALSE and COBS against published reference values, plus properties."""
from hypothesis import given
from hypothesis import strategies as st

from minirquad_driver.protocol import cobs
from minirquad_driver.protocol.crc import crc16_ccitt_false


def _bitwise_crc(data: bytes) -> int:
    """Textbook MSB-first CRC loop (poly 0x1021, init 0xFFFF): an independent implementation."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def test_crc_check_value():
    # Check value from the CRC catalogue (Greg Cook, "CRC-16/IBM-3740" a.k.a. CCITT-FALSE).
    assert crc16_ccitt_false(b'123456789') == 0x29B1


def test_crc_of_nothing_is_the_initial_value():
    assert crc16_ccitt_false(b'') == 0xFFFF


@given(st.binary(max_size=300))
def test_crc_matches_bitwise_loop(data):
    assert crc16_ccitt_false(data) == _bitwise_crc(data)


# Examples from Cheshire and Baker's COBS paper as listed on Wikipedia ("Consistent Overhead
# Byte Stuffing", encoding examples 1-10), without the trailing 0x00 delimiter.
_SEQ_1_FE = bytes(range(1, 0xFF))            # 01..FE, 254 bytes
COBS_VECTORS = [
    (b'\x00', b'\x01\x01'),
    (b'\x00\x00', b'\x01\x01\x01'),
    (b'\x00\x11\x00', b'\x01\x02\x11\x01'),
    (b'\x11\x22\x00\x33', b'\x03\x11\x22\x02\x33'),
    (b'\x11\x22\x33\x44', b'\x05\x11\x22\x33\x44'),
    (b'\x11\x00\x00\x00', b'\x02\x11\x01\x01\x01'),
    (_SEQ_1_FE, b'\xff' + _SEQ_1_FE),
    (b'\x00' + _SEQ_1_FE, b'\x01\xff' + _SEQ_1_FE),
    (_SEQ_1_FE + b'\xff', b'\xff' + _SEQ_1_FE + b'\x02\xff'),
    (bytes(range(2, 0x100)) + b'\x00', b'\xff' + bytes(range(2, 0x100)) + b'\x01\x01'),
    (bytes(range(3, 0x100)) + b'\x00\x01', b'\xfe' + bytes(range(3, 0x100)) + b'\x02\x01'),
]


def test_cobs_reference_vectors():
    for raw, enc in COBS_VECTORS:
        assert cobs.encode(raw) == enc, raw[:8]
        assert cobs.decode(enc) == raw


def test_cobs_empty():
    assert cobs.encode(b'') == b'\x01'
    assert cobs.decode(b'\x01') == b''


@given(st.binary(max_size=1200))
def test_cobs_round_trip_and_no_zero(data):
    enc = cobs.encode(data)
    assert 0 not in enc
    assert len(enc) <= len(data) + len(data) // 254 + 1
    assert cobs.decode(enc) == data


@given(st.binary(max_size=600))
def test_cobs_decode_never_raises_anything_but_cobserror(data):
    try:
        cobs.decode(data)
    except cobs.CobsError:
        pass
