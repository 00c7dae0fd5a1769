"""Typed MiniRQuad protocol messages and their fixed little-endian payload layouts.

Each message is a small frozen dataclass in SI units (rad, rad/s, m, m/s, N). The wire
carries fixed-point integers; ``pack`` rounds to the resolution stated in each docstring and
raises ``ValueError`` for NaN or out-of-range values, ``unpack`` is exact. The full wire
specification, with the reasons for each choice, is ``PROTOCOL.md`` in the package root.

Leg order everywhere: proximal-left, proximal-right, distal-left, distal-right. "Proximal"
legs sit on the axle nearer the winch point p (the rear axle; the winch is at the back).
Leg angles follow the anchor-state convention: measured from -z_B about the axle, positive
forward on both sides (the firmware un-mirrors the right-hand servos).
"""
from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass
from typing import ClassVar

PROTOCOL_VERSION = 2
LEG_COUNT = 4
LEG_NAMES = ('proximal_left', 'proximal_right', 'distal_left', 'distal_right')

# Fixed-point scales, as LSBs per SI unit: SI value = integer / scale. Dividing by an exact
# integer (rather than multiplying by 1e-6) gives the double nearest the decimal value.
MICRORAD = 1_000_000       # angles: 1 urad per LSB (int32)
MILLIRAD_S = 1_000         # angular rates: 1 mrad/s per LSB (int16, +-32.767 rad/s)
MILLINEWTON = 1_000        # tension: 1 mN per LSB (int32)
MICROMETRE = 1_000_000     # spool position: 1 um per LSB (int32, +-2147 m)
MICROMETRE_S = 1_000_000   # spool and winch speed: 1 um/s per LSB (int32)
MILLISECOND = 1_000        # gait period: 1 ms per LSB (uint16)
DUTY_LSB = 10_000          # duty factor: 1e-4 per LSB (uint16)
PHASE_LSB = 65_536         # gait phase: 1/65536 of a cycle per LSB (uint16)

INT16_MAX = 2**15 - 1
INT32_MAX = 2**31 - 1


class MsgType(enum.IntEnum):
    """Message type byte. 0x01-0x0F flow MCU -> host, 0x10-0x1F host -> MCU."""

    TELEMETRY = 0x01
    POWER = 0x02
    ACK = 0x03
    RESET_NOTICE = 0x04
    ERROR = 0x05
    LOG = 0x06
    INFO = 0x07
    HEARTBEAT = 0x10
    SET_LEGS = 0x11
    SET_GAIT = 0x12
    BURROW = 0x13
    WINCH = 0x14
    ESTOP = 0x15
    GET_INFO = 0x16


#: Types the host sends (and the MCU acks).
HOST_TYPES = frozenset(range(0x10, 0x17))


class Mode(enum.IntEnum):
    """What the MCU is doing (telemetry ``mode`` byte)."""

    IDLE = 0          # holding the last targets (stand, or after set_legs)
    WALKING = 1       # legs follow the Buehler clock
    BURROW_RETRACT = 2
    BURROW_FINAL = 3
    ANCHORED = 4      # final burrow pose reached and held
    ESTOPPED = 5
    WATCHDOG = 6      # host heartbeat lost: motors stopped


class Flag(enum.IntFlag):
    """Telemetry ``flags`` bits."""

    ESTOP = 0x0001
    WATCHDOG_TRIPPED = 0x0002
    WINCH_STALLED = 0x0004
    ANCHOR_SLIPPING = 0x0008
    VELOCITY_SATURATED = 0x0010   # a reported rate hit the int16 limit
    SLED_MOVING = 0x0020
    TENSION_INVALID = 0x0040      # the tension field holds no fresh load-cell reading


ALL_FLAGS = 0x007F    # every bit Flag defines; the others are reserved (must be 0)


class BurrowMode(enum.IntEnum):
    """Burrow sequences of the paper's Table II; UNBURROW returns to standing."""

    UNBURROW = 0
    DH = 1
    DL = 2
    SH = 3


class GaitKind(enum.IntEnum):
    STAND = 0   # hold every leg at ``down``
    CLOCK = 1   # Buehler clock with the given period, duty, sweep, down, phases


class AckResult(enum.IntEnum):
    OK = 0
    INVALID = 1        # payload decoded but a value is out of range
    ESTOPPED = 2       # motion command refused while the e-stop is engaged
    UNSUPPORTED = 3    # unknown type or version
    BUSY = 4


class ResetCause(enum.IntEnum):
    POWER_ON = 0
    WATCHDOG = 1
    BROWNOUT = 2
    SOFTWARE = 3
    UNKNOWN = 255


class ErrorCode(enum.IntEnum):
    HOST_WATCHDOG = 1      # no heartbeat within the timeout; motors stopped
    RX_CRC = 2             # MCU rejected a host frame (detail = count so far)
    WINCH_STALL = 3
    SERVO_OVERLOAD = 4
    ANCHOR_SLIP = 5
    WINCH_DEADMAN = 6      # winch speed not refreshed in time; winch stopped (detail = ms)
    WINCH_OVERTENSION = 7  # tension above the rope/anchor limit; winch braked (detail = mN)
    WINCH_SENSOR = 8       # load cell silent; reel-in refused (detail = ms without a reading)


class FieldRangeError(ValueError):
    """A payload of the right size whose enum or flag field holds a value the protocol does
    not define (mode, result code, error code, reset cause, protocol version). The decoder
    counts these apart from size errors: they mean a firmware speaking another dialect."""


def _member(value: int, allowed, name: str) -> int:
    """``value`` if it is one of ``allowed`` (an enum or a set of ints), else FieldRangeError."""
    if value not in {int(a) for a in allowed}:
        raise FieldRangeError(f'{name}={value} is not defined by protocol version '
                              f'{PROTOCOL_VERSION}')
    return value


def _fixed(value: float, scale: float, lo: int, hi: int, name: str) -> int:
    """Round an SI value to its fixed-point integer; reject NaN and out-of-range values."""
    if not math.isfinite(value):
        raise ValueError(f'{name} is not finite: {value!r}')
    q = round(value * scale)
    if q < lo or q > hi:
        raise ValueError(f'{name}={value!r} outside the wire range [{lo / scale}, {hi / scale}]')
    return q


def _uint(value: int, bits: int, name: str) -> int:
    value = int(value)
    if value < 0 or value >= 1 << bits:
        raise ValueError(f'{name}={value} does not fit in uint{bits}')
    return value


# --------------------------------------------------------------------------- MCU -> host


@dataclass(frozen=True)
class Telemetry:
    """Robot state sampled by the MCU at its timestamp (frame header).

    leg_angles: rad, wrapped to (-pi, pi], 1 urad resolution (int32).
    leg_velocities: rad/s, 1 mrad/s resolution (int16, saturates at +-32.767 rad/s and sets
        Flag.VELOCITY_SATURATED on the MCU).
    pitch: body pitch thetaB, rad (anchor-state convention: positive when the axle end is
        higher than the winch point p, i.e. nose up), 1 urad (int32).
    pitch_rate: d(thetaB)/dt, rad/s, 1 mrad/s (int16).
    tension: winch rope tension, N, 1 mN (int32); >= 0 for a rope, a load cell may read a
        little below zero.
    spool_position: rope reeled in since boot, m, 1 um (int32).
    spool_velocity: reel-in speed, m/s, 1 um/s (int32).
    mode: ``Mode``; flags: ``Flag`` bits.
    """

    TYPE: ClassVar[MsgType] = MsgType.TELEMETRY
    _FMT: ClassVar[struct.Struct] = struct.Struct('<4i4hihiiiBH')

    leg_angles: tuple[float, float, float, float]
    leg_velocities: tuple[float, float, float, float]
    pitch: float
    pitch_rate: float
    tension: float
    spool_position: float
    spool_velocity: float
    mode: int = Mode.IDLE
    flags: int = 0

    def pack(self) -> bytes:
        if len(self.leg_angles) != LEG_COUNT or len(self.leg_velocities) != LEG_COUNT:
            raise ValueError('need four leg angles and four leg velocities')
        # 3141593 urad > pi: allow the rounded value of +pi itself.
        ang = [_fixed(a, MICRORAD, -3141593, 3141593, 'leg_angle') for a in self.leg_angles]
        vel = [_fixed(v, MILLIRAD_S, -INT16_MAX, INT16_MAX, 'leg_velocity')
               for v in self.leg_velocities]
        return self._FMT.pack(
            *ang, *vel,
            _fixed(self.pitch, MICRORAD, -3141593, 3141593, 'pitch'),
            _fixed(self.pitch_rate, MILLIRAD_S, -INT16_MAX, INT16_MAX, 'pitch_rate'),
            _fixed(self.tension, MILLINEWTON, -INT32_MAX, INT32_MAX, 'tension'),
            _fixed(self.spool_position, MICROMETRE, -INT32_MAX, INT32_MAX, 'spool_position'),
            _fixed(self.spool_velocity, MICROMETRE_S, -INT32_MAX, INT32_MAX, 'spool_velocity'),
            _uint(int(self.mode), 8, 'mode'), _uint(int(self.flags), 16, 'flags'))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Telemetry':
        v = cls._FMT.unpack(payload)
        for raw in v[0:4] + (v[8],):
            if abs(raw) > 3141593:
                raise ValueError('angle outside (-pi, pi]')
        _member(v[13], Mode, 'mode')
        if v[14] & ~ALL_FLAGS:
            raise FieldRangeError(f'flags=0x{v[14]:04x} sets undefined bits')
        return cls(
            leg_angles=tuple(a / MICRORAD for a in v[0:4]),
            leg_velocities=tuple(w / MILLIRAD_S for w in v[4:8]),
            pitch=v[8] / MICRORAD, pitch_rate=v[9] / MILLIRAD_S,
            tension=v[10] / MILLINEWTON, spool_position=v[11] / MICROMETRE,
            spool_velocity=v[12] / MICROMETRE_S, mode=v[13], flags=v[14])


@dataclass(frozen=True)
class Power:
    """Raw INA219 registers, exactly as the chip reports them (see ``ina219.py``).

    bus: register 0x02 (bits 15..3 = bus voltage in 4 mV LSBs, bit 1 CNVR, bit 0 OVF).
    shunt: register 0x01, signed, 10 uV per LSB.
    current: register 0x04, signed, current LSB = 0.04096 / (cal * R_shunt) A.
    power: register 0x03, unsigned, power LSB = 20 * current LSB W.
    cal: register 0x05 as read back; 0 means the chip reset and current/power are invalid.
    """

    TYPE: ClassVar[MsgType] = MsgType.POWER
    _FMT: ClassVar[struct.Struct] = struct.Struct('<HhhHH')

    bus: int
    shunt: int
    current: int
    power: int
    cal: int

    def pack(self) -> bytes:
        return self._FMT.pack(_uint(self.bus, 16, 'bus'), self.shunt, self.current,
                              _uint(self.power, 16, 'power'), _uint(self.cal, 16, 'cal'))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Power':
        return cls(*cls._FMT.unpack(payload))


@dataclass(frozen=True)
class Ack:
    """Answer to a host command: echoes the command's sequence number and type."""

    TYPE: ClassVar[MsgType] = MsgType.ACK
    _FMT: ClassVar[struct.Struct] = struct.Struct('<BBB')

    acked_seq: int
    acked_type: int
    result: int = AckResult.OK

    def pack(self) -> bytes:
        return self._FMT.pack(_uint(self.acked_seq, 8, 'acked_seq'),
                              _uint(int(self.acked_type), 8, 'acked_type'),
                              _uint(int(self.result), 8, 'result'))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Ack':
        seq, acked_type, result = cls._FMT.unpack(payload)
        _member(acked_type, HOST_TYPES, 'acked_type')
        _member(result, AckResult, 'result')
        return cls(seq, acked_type, result)


@dataclass(frozen=True)
class _About:
    """Firmware identity and configured rates (shared by RESET_NOTICE and INFO).

    protocol_version: the layout version the firmware speaks.
    firmware_version: opaque build number.
    reset_cause: ``ResetCause`` of the last boot.
    telemetry_hz, power_hz: configured stream rates, Hz.
    """

    _FMT: ClassVar[struct.Struct] = struct.Struct('<BHBHH')

    protocol_version: int
    firmware_version: int
    reset_cause: int
    telemetry_hz: int
    power_hz: int

    def pack(self) -> bytes:
        return self._FMT.pack(_uint(self.protocol_version, 8, 'protocol_version'),
                              _uint(self.firmware_version, 16, 'firmware_version'),
                              _uint(int(self.reset_cause), 8, 'reset_cause'),
                              _uint(self.telemetry_hz, 16, 'telemetry_hz'),
                              _uint(self.power_hz, 16, 'power_hz'))

    @classmethod
    def unpack(cls, payload: bytes):
        v = cls._FMT.unpack(payload)
        _member(v[0], (PROTOCOL_VERSION,), 'protocol_version')
        _member(v[2], ResetCause, 'reset_cause')
        return cls(*v)


@dataclass(frozen=True)
class ResetNotice(_About):
    """Sent once, unprompted, right after the MCU boots: the host restarts its baselines."""

    TYPE: ClassVar[MsgType] = MsgType.RESET_NOTICE


@dataclass(frozen=True)
class Info(_About):
    """Reply to GET_INFO."""

    TYPE: ClassVar[MsgType] = MsgType.INFO


@dataclass(frozen=True)
class Error:
    """Something went wrong on the MCU: ``ErrorCode`` plus a code-specific 16-bit detail."""

    TYPE: ClassVar[MsgType] = MsgType.ERROR
    _FMT: ClassVar[struct.Struct] = struct.Struct('<BH')

    code: int
    detail: int = 0

    def pack(self) -> bytes:
        return self._FMT.pack(_uint(int(self.code), 8, 'code'), _uint(self.detail, 16, 'detail'))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Error':
        code, detail = cls._FMT.unpack(payload)
        _member(code, ErrorCode, 'code')
        return cls(code, detail)


@dataclass(frozen=True)
class Log:
    """Human-readable debug text (UTF-8, at most 200 bytes), kept out of the binary stream."""

    TYPE: ClassVar[MsgType] = MsgType.LOG
    MAX_BYTES: ClassVar[int] = 200

    text: str

    def pack(self) -> bytes:
        data = self.text.encode('utf-8')
        if len(data) > self.MAX_BYTES:
            raise ValueError('log text longer than 200 bytes')
        return data

    @classmethod
    def unpack(cls, payload: bytes) -> 'Log':
        if len(payload) > cls.MAX_BYTES:
            raise ValueError('log text longer than 200 bytes')
        return cls(payload.decode('utf-8', errors='replace'))


# --------------------------------------------------------------------------- host -> MCU


@dataclass(frozen=True)
class _Empty:
    def pack(self) -> bytes:
        return b''

    @classmethod
    def unpack(cls, payload: bytes):
        if payload:
            raise ValueError(f'{cls.__name__} takes no payload')
        return cls()


@dataclass(frozen=True)
class Heartbeat(_Empty):
    """Host is alive. The MCU stops the motors if none arrives within its watchdog timeout
    (500 ms); it acks each heartbeat, which gives the host a round-trip latency figure."""

    TYPE: ClassVar[MsgType] = MsgType.HEARTBEAT


@dataclass(frozen=True)
class GetInfo(_Empty):
    TYPE: ClassVar[MsgType] = MsgType.GET_INFO


@dataclass(frozen=True)
class SetLegs:
    """Leg position targets, rad (1 urad), for the legs whose bit is set in ``mask``
    (bit i = leg i in LEG_NAMES order). The MCU moves each leg at its speed limit."""

    TYPE: ClassVar[MsgType] = MsgType.SET_LEGS
    _FMT: ClassVar[struct.Struct] = struct.Struct('<B4i')

    targets: tuple[float, float, float, float]
    mask: int = 0x0F

    def pack(self) -> bytes:
        if len(self.targets) != LEG_COUNT:
            raise ValueError('need four leg targets')
        return self._FMT.pack(_uint(self.mask, 4, 'mask'),
                              *(_fixed(t, MICRORAD, -3141593, 3141593, 'leg_target')
                                for t in self.targets))

    @classmethod
    def unpack(cls, payload: bytes) -> 'SetLegs':
        v = cls._FMT.unpack(payload)
        if v[0] > 0x0F or any(abs(t) > 3141593 for t in v[1:]):
            raise ValueError('bad SET_LEGS payload')
        return cls(targets=tuple(t / MICRORAD for t in v[1:]), mask=v[0])


@dataclass(frozen=True)
class SetGait:
    """Gait as data: a Buehler clock per leg (MiniRHex scheme).

    kind: ``GaitKind``. STAND holds every leg at ``down``.
    period: cycle time, s (1 ms, 0.05 .. 65.535 s).
    duty: fraction of the cycle spent in the slow (stance) arc, 0 < duty < 1 (1e-4).
    sweep: width of the slow arc, rad, 0 < sweep < 2 pi (1 urad).
    down: centre of the slow arc, rad (1 urad).
    phases: per-leg phase offsets, fraction of a cycle in [0, 1) (1/65536).
    direction: +1 forward (away from p: the toes sweep back in stance, the angle falls),
    -1 reverse.
    """

    TYPE: ClassVar[MsgType] = MsgType.SET_GAIT
    _FMT: ClassVar[struct.Struct] = struct.Struct('<BHHii4Hb')

    kind: int
    period: float = 1.0
    duty: float = 0.5
    sweep: float = 0.7
    down: float = 0.0
    phases: tuple[float, float, float, float] = (0.0, 0.5, 0.5, 0.0)
    direction: int = 1

    def pack(self) -> bytes:
        if len(self.phases) != LEG_COUNT:
            raise ValueError('need four phases')
        if self.direction not in (1, -1):
            raise ValueError('direction must be +1 or -1')
        return self._FMT.pack(
            _uint(int(self.kind), 8, 'kind'),
            _fixed(self.period, MILLISECOND, 50, 65535, 'period'),
            _fixed(self.duty, DUTY_LSB, 1, 9999, 'duty'),
            _fixed(self.sweep, MICRORAD, 1, 6283184, 'sweep'),
            _fixed(self.down, MICRORAD, -3141593, 3141593, 'down'),
            *(_fixed(p, PHASE_LSB, 0, 65535, 'phase') for p in self.phases),
            self.direction)

    @classmethod
    def unpack(cls, payload: bytes) -> 'SetGait':
        v = cls._FMT.unpack(payload)
        if (v[0] not in tuple(GaitKind) or v[1] < 50 or not 1 <= v[2] <= 9999
                or not 1 <= v[3] <= 6283184 or abs(v[4]) > 3141593 or v[9] not in (1, -1)):
            raise ValueError('bad SET_GAIT payload')
        return cls(kind=v[0], period=v[1] / MILLISECOND, duty=v[2] / DUTY_LSB,
                   sweep=v[3] / MICRORAD, down=v[4] / MICRORAD,
                   phases=tuple(p / PHASE_LSB for p in v[5:9]),
                   direction=v[9])


@dataclass(frozen=True)
class Burrow:
    """Run a Table II burrow sequence (retracting pose, then final pose) or unburrow."""

    TYPE: ClassVar[MsgType] = MsgType.BURROW
    _FMT: ClassVar[struct.Struct] = struct.Struct('<B')

    mode: int

    def pack(self) -> bytes:
        if int(self.mode) not in tuple(BurrowMode):
            raise ValueError(f'unknown burrow mode {self.mode}')
        return self._FMT.pack(int(self.mode))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Burrow':
        (mode,) = cls._FMT.unpack(payload)
        if mode not in tuple(BurrowMode):
            raise ValueError(f'unknown burrow mode {mode}')
        return cls(mode)


@dataclass(frozen=True)
class Winch:
    """Winch reel-in speed, m/s (1 um/s); negative pays out, 0 brakes. ``hold``: s (1 ms) this
    speed may run after the MCU received it unless a newer WINCH replaces it, at most 65.535 s;
    0 sets no limit of its own (the MCU's winch deadman still applies). A commander sets it from
    the age of the evidence the speed rests on, so the MCU stops a winch whose evidence ran out
    whatever happens on the host."""

    TYPE: ClassVar[MsgType] = MsgType.WINCH
    _FMT: ClassVar[struct.Struct] = struct.Struct('<iH')

    speed: float
    hold: float = 0.0

    def pack(self) -> bytes:
        return self._FMT.pack(_fixed(self.speed, MICROMETRE_S, -1_000_000, 1_000_000, 'speed'),
                              _fixed(self.hold, 1e3, 0, 0xFFFF, 'hold'))

    @classmethod
    def unpack(cls, payload: bytes) -> 'Winch':
        v, hold_ms = cls._FMT.unpack(payload)
        if abs(v) > 1_000_000:
            raise ValueError('winch speed above 1 m/s')
        return cls(v / MICROMETRE_S, hold_ms / 1e3)


@dataclass(frozen=True)
class EStop:
    """Engage (True) or release (False) the emergency stop: legs hold, winch brakes."""

    TYPE: ClassVar[MsgType] = MsgType.ESTOP
    _FMT: ClassVar[struct.Struct] = struct.Struct('<B')

    engage: bool

    def pack(self) -> bytes:
        return self._FMT.pack(1 if self.engage else 0)

    @classmethod
    def unpack(cls, payload: bytes) -> 'EStop':
        (v,) = cls._FMT.unpack(payload)
        if v > 1:
            raise ValueError('estop byte must be 0 or 1')
        return cls(bool(v))


Message = (Telemetry | Power | Ack | ResetNotice | Info | Error | Log | Heartbeat | GetInfo
           | SetLegs | SetGait | Burrow | Winch | EStop)

MESSAGE_CLASSES: dict[int, type] = {
    cls.TYPE: cls for cls in (Telemetry, Power, Ack, ResetNotice, Info, Error, Log, Heartbeat,
                              GetInfo, SetLegs, SetGait, Burrow, Winch, EStop)}

#: Commands the host may resend after an ack timeout because repeating them is harmless.
IDEMPOTENT_COMMANDS = frozenset({MsgType.SET_LEGS, MsgType.SET_GAIT, MsgType.BURROW,
                                 MsgType.WINCH, MsgType.ESTOP, MsgType.GET_INFO})

#: What each host command sets on the MCU: a newer command of the same channel replaces what
#: an older one set. The legs follow one of leg targets, a gait or a burrow, whichever came
#: last; the winch runs at its last speed; the e-stop is engaged or released.
COMMAND_CHANNEL: dict[MsgType, str] = {
    MsgType.SET_LEGS: 'legs', MsgType.SET_GAIT: 'legs', MsgType.BURROW: 'legs',
    MsgType.WINCH: 'winch', MsgType.ESTOP: 'estop', MsgType.GET_INFO: 'info'}
