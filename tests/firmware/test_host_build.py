"""The firmware core on the host: its unit tests (golden frames included), the fuzz test under
the sanitizers, a differential test of its decoder against the Python codec, and the
Cortex-M0+ size check."""
from __future__ import annotations

import re
import shutil
import struct
import subprocess

import pytest
from firmware_host import FIRMWARE, make
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import any_message

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

GOLDEN = FIRMWARE / 'tests' / 'golden_frames.txt'
COUNTERS = ('frames', 'cobs_errors', 'crc_errors', 'short_frames', 'version_errors',
            'unknown_types', 'payload_errors', 'range_errors', 'overflows', 'bytes_in')


def _run(argv, timeout=120.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in argv], capture_output=True, text=True,
                          timeout=timeout)


def test_unit_tests_and_golden_frames_byte_for_byte(firmware_build):
    res = _run([firmware_build / 'test_core', GOLDEN])
    assert res.returncode == 0, res.stdout + res.stderr
    assert re.search(r'\d+ tests, \d+ checks, 0 failures', res.stdout), res.stdout
    golden = re.search(r'golden: (\d+) ok frames, (\d+) payload errors, (\d+) range errors',
                       res.stdout)
    assert golden, res.stdout
    ok, payload, rng = map(int, golden.groups())
    rows = [ln.split()[2] for ln in GOLDEN.read_text().splitlines() if ln.startswith('frame')]
    assert (ok, payload, rng) == (rows.count('ok'), rows.count('payload'), rows.count('range'))
    assert 'FAIL' not in res.stdout and not res.stderr


def test_fuzz_a_million_bytes_under_the_sanitizers(firmware_build):
    res = _run([firmware_build / 'fuzz', '--bytes', '1000000', '--seed', '1'])
    assert res.returncode == 0, res.stdout + res.stderr[-3000:]
    dec = re.search(r'decoder: (\d+) bytes in (\d+) streams, ([\d.]+) s', res.stdout)
    cmd = re.search(r'handler: (\d+) bytes, (\d+) acks, ([\d.]+) s', res.stdout)
    assert dec and cmd, res.stdout
    assert int(dec.group(1)) >= 10**6 and int(cmd.group(1)) >= 10**6
    assert int(cmd.group(2)) > 10_000            # the handler really answered commands
    assert 'no findings' in res.stdout and not res.stderr
    print(f'\n[fuzz] {res.stdout.strip()}')


@pytest.mark.parametrize('canary, report', [('--canary-asan', 'AddressSanitizer'),
                                            ('--canary-ubsan', 'runtime error')])
def test_the_sanitizers_are_live_in_the_host_build(firmware_build, canary, report):
    """A deliberate out-of-bounds write and signed overflow stop the fuzz binary: the fuzz
    test's silence means something."""
    res = _run([firmware_build / 'fuzz', canary])
    assert res.returncode != 0 and report in res.stderr, res.stderr[-2000:]


_junk = st.binary(min_size=1, max_size=300)


@st.composite
def streams(draw):
    """Intact frames of every type, junk, and frames with flipped bits or cut short."""
    parts = []
    for _ in range(draw(st.integers(1, 12))):
        kind = draw(st.sampled_from(['frame', 'junk', 'flip', 'cut']))
        if kind == 'junk':
            parts.append(draw(_junk))
            continue
        fr = bytearray(encode_frame(draw(any_message), draw(st.integers(0, 255)),
                                    draw(st.integers(0, 2**32 - 1))))
        if kind == 'flip':
            pos = draw(st.integers(1, len(fr) - 2))
            fr[pos] ^= 1 << draw(st.integers(0, 7))
        elif kind == 'cut':
            fr = fr[:draw(st.integers(1, len(fr) - 2))]
        parts.append(bytes(fr))
    return b''.join(parts) + b'\x00'


def _compare(build, batch: list[bytes]) -> int:
    """Decode each stream with fw_codec and with the Python FrameDecoder; assert they agree
    frame for frame (type, seq, stamp, payload bytes) and counter for counter."""
    data = b''.join(struct.pack('<I', len(s)) + s for s in batch)
    res = subprocess.run([str(build / 'fw_codec')], input=data, capture_output=True,
                         timeout=60)
    assert res.returncode == 0, res.stderr.decode()[-2000:]
    lines = res.stdout.decode().splitlines()
    frames = 0
    for s in batch:
        dec = FrameDecoder()
        want = [f'F {int(f.message.TYPE)} {f.seq} {f.t_mcu_ms} {f.message.pack().hex() or "-"}'
                for f in dec.feed(s)]
        got = []
        while lines and lines[0].startswith('F '):
            got.append(lines.pop(0))
        counters = lines.pop(0).split()[1:]
        assert got == want
        assert [int(c) for c in counters] == [getattr(dec.stats, k) for k in COUNTERS]
        frames += len(want)
    assert not lines
    return frames


@settings(max_examples=25, deadline=None)
@given(st.lists(streams(), min_size=1, max_size=20))
def test_cpp_decoder_agrees_with_python_on_any_stream(firmware_build, batch):
    _compare(firmware_build, batch)


def test_cpp_decoder_agrees_with_python_on_two_thousand_random_streams(firmware_build):
    """The same comparison over a seeded batch too big for hypothesis to draw quickly."""
    import random
    rng = random.Random(7)
    batch = []
    for _ in range(2000):
        wire = b''
        for _ in range(rng.randint(1, 10)):
            kind = rng.random()
            if kind < 0.3:
                wire += rng.randbytes(rng.randint(1, 400))
                continue
            msg = _random_message(rng)
            fr = bytearray(encode_frame(msg, rng.randrange(256), rng.randrange(2**32)))
            if kind < 0.5:
                fr[rng.randint(1, len(fr) - 2)] ^= 1 << rng.randrange(8)
            elif kind < 0.6:
                fr = fr[:rng.randint(1, len(fr) - 2)]
            wire += bytes(fr)
        batch.append(wire + b'\x00')
    assert _compare(firmware_build, batch) > 3000   # intact frames compared


def _random_message(rng):
    """A valid message of a random type (field values drawn inside their wire ranges)."""
    angle = lambda: rng.uniform(-3.14159, 3.14159)  # noqa: E731
    kind = rng.randrange(8)
    if kind == 0:
        return m.Telemetry(tuple(angle() for _ in range(4)),
                           tuple(rng.uniform(-32, 32) for _ in range(4)), angle(),
                           rng.uniform(-32, 32), rng.uniform(-100, 100), rng.uniform(-9, 9),
                           rng.uniform(-1, 1), rng.choice(list(m.Mode)),
                           rng.randrange(m.ALL_FLAGS + 1))
    if kind == 1:
        return m.Power(rng.randrange(65536), rng.randrange(-32768, 32768),
                       rng.randrange(-32768, 32768), rng.randrange(65536), rng.randrange(65536))
    if kind == 2:
        return m.Ack(rng.randrange(256), rng.choice(sorted(m.HOST_TYPES)),
                     rng.choice(list(m.AckResult)))
    if kind == 3:
        return m.Log(''.join(chr(rng.randrange(32, 127)) for _ in range(rng.randrange(200))))
    if kind == 4:
        return m.SetGait(rng.choice(list(m.GaitKind)), rng.uniform(0.05, 60),
                         rng.uniform(0.01, 0.99), rng.uniform(0.01, 6.2), angle(),
                         tuple(rng.random() * 0.999 for _ in range(4)), rng.choice([1, -1]))
    if kind == 5:
        return m.SetLegs(tuple(angle() for _ in range(4)), rng.randrange(16))
    if kind == 6:
        return m.Winch(rng.uniform(-1, 1))
    return rng.choice([m.Heartbeat(), m.GetInfo(), m.EStop(rng.random() < 0.5),
                       m.Burrow(rng.choice(list(m.BurrowMode))),
                       m.Error(rng.choice(list(m.ErrorCode)), rng.randrange(65536))])


def test_cross_compiled_core_fits_the_mkr_wifi_1010():
    if not shutil.which('arm-none-eabi-gcc'):
        pytest.skip('arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi)')
    res = make('size')
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    flash = re.search(r'flash +(\d+) B of (\d+)', res.stdout)
    ram = re.search(r'RAM +(\d+) B of (\d+)', res.stdout)
    assert flash and ram, res.stdout
    assert int(flash.group(2)) == 256 * 1024 - 8 * 1024 and int(ram.group(2)) == 32 * 1024
    assert 0 < int(flash.group(1)) <= int(flash.group(2))
    assert 0 < int(ram.group(1)) <= int(ram.group(2))
    assert 'no malloc/free/new/delete/__cxa_*/unwinder symbols' in res.stdout
    print('\n' + '\n'.join(ln for ln in res.stdout.splitlines() if ln.startswith(' ')))


def test_the_size_check_fails_on_heap_use(tmp_path):
    """The forbidden-symbol check is not a formality: an ELF that links malloc fails it."""
    if not shutil.which('arm-none-eabi-gcc'):
        pytest.skip('arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi)')
    src = tmp_path / 'heap.c'
    src.write_text('#include <stdlib.h>\n'
                   'void Reset_Handler(void) { void* volatile p = malloc(8); free(p); }\n'
                   'int main(void) { return 0; }\n')
    elf = tmp_path / 'heap.elf'
    subprocess.run(['arm-none-eabi-gcc', '-mcpu=cortex-m0plus', '-mthumb', '-Os',
                    '--specs=nano.specs', '--specs=nosys.specs', '-nostartfiles',
                    '-T', str(FIRMWARE / 'arm' / 'mkrwifi1010.ld'), str(src), '-o', str(elf)],
                   check=True, capture_output=True)
    res = _run(['python3', FIRMWARE / 'arm' / 'size_report.py', '--size', 'arm-none-eabi-size',
                '--nm', 'arm-none-eabi-nm', '--flash', '253952', '--ram', '32768', elf])
    assert res.returncode == 1 and 'FAIL: heap' in res.stdout and 'malloc' in res.stdout
