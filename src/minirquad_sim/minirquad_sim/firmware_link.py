"""The plant's end of the software-in-the-loop link to the compiled firmware (``fw_sitl``).

One exchange per firmware ``loop()`` over an AF_UNIX SOCK_SEQPACKET socketpair (message
boundaries kept, EOF when a peer dies): a ``PlantFrame`` (simulated time, sensor values, the
serial bytes the host sent) goes down, a ``FwFrame`` (actuator outputs, the serial bytes the
firmware wrote) comes back. The layouts are the C++ structs of
src/minirquad_driver/firmware/sitl/sitl_link.h, little-endian and packed; a magic, version or
size mismatch is an error, never a guess.
"""
from __future__ import annotations

import os
import socket
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

import minirquad_driver

PLANT_MAGIC = 0x5153524D
FW_MAGIC = 0x4651524D
HELLO_MAGIC = 0x4851524D
VERSION = 1
MAX_SERIAL = 4096
CMD_RUN, CMD_RESET = 0, 1

HELLO = struct.Struct('<IHH4i4bfifHH')
PLANT = struct.Struct('<IHHIQBBBB4i4i4h4H6HBBiiihH')
FW = struct.Struct('<IHHIII4ihBBB4B4HBBBBIIIIH')


class FirmwareLinkError(RuntimeError):
    """The firmware process is missing, died, hung, or speaks another layout."""


def default_binary() -> Path:
    """fw_sitl as `make setup` builds it (``MINIRQUAD_FW_SITL`` overrides the path)."""
    env = os.environ.get('MINIRQUAD_FW_SITL')
    if env:
        return Path(env)
    return (Path(minirquad_driver.__file__).resolve().parents[1] / 'firmware' / 'build'
            / 'fw_sitl')


@dataclass(frozen=True)
class Hello:
    """The calibration the firmware was built with."""

    leg_zero: tuple[int, ...]
    leg_sign: tuple[int, ...]
    winch_um_per_count: float
    load_cell_tare: int
    load_cell_mn_per_count: float
    ina219_cal: int
    control_period_ms: int


@dataclass(frozen=True)
class Sensors:
    """What the plant's hardware reports at one instant (wire units, see sitl_link.h)."""

    servo_position: tuple[int, ...]
    servo_velocity: tuple[int, ...]
    ina219: tuple[int, ...]
    load_cell_seq: int
    load_cell_raw: int
    winch_encoder: int
    pitch: int
    pitch_rate: int
    servo_ok: int = 0x0F
    imu_ok: bool = True
    ina219_ok: bool = True
    servo_current: tuple[int, ...] = (0, 0, 0, 0)
    servo_voltage: tuple[int, ...] = (50, 50, 50, 50)


@dataclass(frozen=True)
class Outputs:
    """One FwFrame: the firmware's outputs after one loop()."""

    frame: int
    fw_ms: int
    next_due_ms: int
    goal_velocity: tuple[int, ...]
    winch_duty: int
    winch_brake: bool
    watchdog_kicked: bool
    ina219_writes: tuple[tuple[int, int], ...]
    motion_mode: int
    burrow_mode: int
    unburrowing: bool
    next_seq: int
    rx_frames: int
    rx_rejected: int
    rx_crc_errors: int
    tx_dropped: int
    tx: bytes


class FirmwareProcess:
    """fw_sitl as a child process on one end of a socketpair.

    ``args``: its options (--clock-start-ms, --telemetry-hz, ...). ``timeout``: s an
    exchange may take before the firmware counts as hung.
    """

    def __init__(self, binary: Path | None = None, args: list[str] | None = None,
                 timeout: float = 5.0):
        self.binary = Path(binary) if binary else default_binary()
        if not os.access(self.binary, os.X_OK):
            raise FirmwareLinkError(f'{self.binary} not found: build it with `make setup` '
                                    f'(or `make -C src/minirquad_driver/firmware host`)')
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.sock = ours
        self.sock.settimeout(timeout)
        self.proc = subprocess.Popen([str(self.binary), '--fd', str(theirs.fileno()),
                                      *(args or [])], pass_fds=[theirs.fileno()])
        theirs.close()
        self.frame = 0
        self.hello = self._read_hello()

    def _recv(self, size: int) -> bytes:
        try:
            data = self.sock.recv(size)
        except TimeoutError as exc:
            raise FirmwareLinkError('the firmware did not answer: hung') from exc
        if not data:
            code = self.proc.poll()
            raise FirmwareLinkError(f'the firmware exited (status {code}); its stderr says why')
        return data

    def _read_hello(self) -> Hello:
        data = self._recv(HELLO.size + 16)
        if len(data) != HELLO.size:
            raise FirmwareLinkError(f'hello of {len(data)} bytes, expected {HELLO.size}')
        v = HELLO.unpack(data)
        if (v[0], v[1], v[2]) != (HELLO_MAGIC, VERSION, HELLO.size):
            raise FirmwareLinkError('the firmware speaks another SITL layout')
        return Hello(tuple(v[3:7]), tuple(v[7:11]), v[11], v[12], v[13], v[14], v[15])

    def exchange(self, sim_us: int, sensors: Sensors, rx: bytes = b'', command: int = CMD_RUN,
                 reset_cause: int = 0) -> Outputs:
        """One firmware loop() at simulated time sim_us (us since the plant started)."""
        if len(rx) > MAX_SERIAL:
            raise ValueError(f'{len(rx)} serial bytes in one exchange (max {MAX_SERIAL})')
        self.frame = (self.frame + 1) & 0xFFFFFFFF
        s = sensors
        head = PLANT.pack(PLANT_MAGIC, VERSION, PLANT.size, self.frame, sim_us, command,
                          reset_cause, s.servo_ok, int(s.imu_ok), *s.servo_position,
                          *s.servo_velocity, *s.servo_current, *s.servo_voltage, *s.ina219,
                          int(s.ina219_ok), s.load_cell_seq, s.load_cell_raw, s.winch_encoder,
                          s.pitch, s.pitch_rate, len(rx))
        try:
            self.sock.send(head + rx)
        except OSError as exc:
            raise FirmwareLinkError(f'the firmware is gone: {exc}') from exc
        data = self._recv(FW.size + MAX_SERIAL + 16)
        v = FW.unpack_from(data)
        if (v[0], v[1], v[2], v[3]) != (FW_MAGIC, VERSION, FW.size, self.frame):
            raise FirmwareLinkError('firmware frame layout or sequence mismatch')
        tx_len = v[-1]
        if len(data) != FW.size + tx_len:
            raise FirmwareLinkError(f'firmware frame of {len(data)} bytes, '
                                    f'header says {FW.size + tx_len}')
        n_writes = v[13]
        return Outputs(frame=v[3], fw_ms=v[4], next_due_ms=v[5], goal_velocity=tuple(v[6:10]),
                       winch_duty=v[10], winch_brake=bool(v[11]), watchdog_kicked=bool(v[12]),
                       ina219_writes=tuple(zip(v[14:18], v[18:22]))[:n_writes],
                       motion_mode=v[22], burrow_mode=v[23], unburrowing=bool(v[24]),
                       next_seq=v[25], rx_frames=v[26], rx_rejected=v[27],
                       rx_crc_errors=v[28], tx_dropped=v[29], tx=bytes(data[FW.size:]))

    def close(self) -> None:
        """Close the socket (the firmware exits on EOF), then make sure it did."""
        self.sock.close()
        try:
            self.proc.wait(2.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(2.0)
