"""The compiled firmware as the simulated robot's microcontroller (``minirquad_sim --mcu
firmware``): the same interface as the Python reference ``SimMcu``, so the pty, the fault
injection and the recorder of ``main.py`` work unchanged.

Per ``tick`` (and whenever host bytes arrived) the plant steps its physics up to ``now``,
reads its sensors, and runs one firmware ``loop()`` at that simulated time through
``fw_sitl`` (firmware_link.py); the firmware's goal velocities, winch PWM and INA219 writes
act on the plant from then on. The plant is the master clock: ``now`` is whatever the caller
says. ``main.py`` passes the wall clock (the real bridge on the pty has wall-clock timers:
heartbeats, ack timeouts, and a clock-drift allowance of 2e-4 s/s), tests may pass any
time base (lockstep, faster or slower than real time).
"""
from __future__ import annotations

import math
from collections.abc import Callable

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder

from .firmware_link import (
    CMD_RESET,
    CMD_RUN,
    MAX_SERIAL,
    FirmwareLinkError,
    FirmwareProcess,
    Sensors,
)
from .mcu import McuConfig
from .plant import PlantRobot, RobotBuild

_KINDS = {m.MsgType.TELEMETRY: 'telemetry', m.MsgType.POWER: 'power', m.MsgType.ACK: 'ack',
          m.MsgType.RESET_NOTICE: 'notice', m.MsgType.ERROR: 'error', m.MsgType.LOG: 'log',
          m.MsgType.INFO: 'info'}


def check_calibration(hello, build: RobotBuild) -> None:
    """The firmware must be calibrated for the robot the plant simulates."""
    wrong = []
    if tuple(hello.leg_zero) != tuple(build.leg_zero):
        wrong.append(f'leg zeros {hello.leg_zero} != {build.leg_zero}')
    if tuple(hello.leg_sign) != tuple(build.leg_sign):
        wrong.append(f'leg signs {hello.leg_sign} != {build.leg_sign}')
    if not math.isclose(hello.winch_um_per_count, build.winch_um_per_count, rel_tol=1e-5):
        wrong.append('winch encoder scale')
    if hello.load_cell_tare != build.load_cell_tare or not math.isclose(
            hello.load_cell_mn_per_count, build.load_cell_mn_per_count, rel_tol=1e-5):
        wrong.append('load-cell calibration')
    if hello.ina219_cal != build.ina219_cal:
        wrong.append('INA219 calibration')
    if wrong:
        raise FirmwareLinkError('the firmware is calibrated for another robot: '
                                + '; '.join(wrong))


class FirmwareMcu:
    """Frames in, frames out, with the compiled firmware deciding what goes out.

    ``on_telemetry(seq, t_ms, Telemetry)`` is called for every telemetry frame the firmware
    writes (before any fault injection), as ``SimMcu`` does. ``binary``: fw_sitl to run.
    """

    def __init__(self, robot_factory: Callable[[], PlantRobot] = PlantRobot,
                 config: McuConfig | None = None,
                 on_telemetry: Callable[[int, int, m.Telemetry], None] | None = None,
                 now: float = 0.0, binary=None):
        self.config = config or McuConfig()
        self.on_telemetry = on_telemetry
        self.robot = robot_factory()
        if not isinstance(self.robot, PlantRobot):
            raise TypeError('the firmware drives a PlantRobot (velocity servos, PWM winch)')
        c = self.config
        self.fw = FirmwareProcess(binary, [
            '--telemetry-hz', str(c.telemetry_hz), '--power-hz', str(c.power_hz),
            '--watchdog-ms', str(round(1000 * c.watchdog_s)),
            '--winch-deadman-ms', str(round(1000 * c.winch_deadman_s)),
            '--clock-start-ms', str(c.clock_start_ms & 0xFFFFFFFF)])
        try:
            check_calibration(self.fw.hello, self.robot.build)
        except FirmwareLinkError:
            self.fw.close()
            raise
        self.period = self.fw.hello.control_period_ms / 1000.0
        self.resets = 0
        self.seq = 0
        self.rx_crc_errors = 0
        self.exchanges = 0
        self.late = 0                      # exchanges a control period or more behind
        self._t0 = now
        self._last_step = now
        self._boot_t = now
        self._clock0 = c.clock_start_ms & 0xFFFFFFFF
        self._next_due = now
        self._booted = False
        self._rx = bytearray()
        self._last_tel: m.Telemetry | None = None

    # ------------------------------------------------------------------ lifecycle
    def notice(self, now: float, cause: int = m.ResetCause.POWER_ON) -> bytes:
        """Power on: the firmware runs its set-up, which sends the RESET_NOTICE only."""
        self._booted = True
        return self._first_frame(self._exchange(now, CMD_RUN, 0))

    def reset(self, now: float, cause: int = m.ResetCause.WATCHDOG) -> bytes:
        """The MCU reboots (the plant stays as it is): clock and seq restart from zero."""
        self.resets += 1
        self._booted = True
        self._boot_t = now
        self._clock0 = 0
        self._rx.clear()                   # bytes in flight to a rebooting MCU are lost
        return self._first_frame(self._exchange(now, CMD_RESET, int(cause)))

    def close(self) -> None:
        self.fw.close()

    def clock_ms(self, now: float) -> int:
        return (self._clock0 + int((now - self._boot_t) * 1000.0)) & 0xFFFFFFFF

    # ------------------------------------------------------------------ host -> MCU
    def receive(self, data: bytes, now: float) -> bytes:
        """Host bytes; the firmware reads them at the next ``tick`` (called right after)."""
        self._rx += data
        return b''

    # ------------------------------------------------------------------ MCU loop
    def tick(self, now: float) -> list[tuple[str, bytes, m.Telemetry | None]]:
        """Run the firmware if it has work (a control cycle due, or host bytes); return the
        frames it wrote as (kind, bytes, telemetry-or-None), at most one telemetry frame per
        call (as SimMcu), so a caller can match each to its fate."""
        out: list[tuple[str, bytes, m.Telemetry | None]] = []
        if not self._booted:
            self._booted = True
            out = self._exchange(now, CMD_RUN, 0)
        elif self._rx or now >= self._next_due:
            if now - self._next_due >= self.period:
                self.late += 1
            out = self._exchange(now, CMD_RUN, 0)
        for _kind, wire, tel in out:
            if tel is not None and self.on_telemetry:
                f = FrameDecoder().feed(wire)[0]
                self.on_telemetry(f.seq, f.t_mcu_ms, tel)
        return out

    def next_due(self) -> float:
        return self._next_due

    def telemetry(self) -> m.Telemetry:
        """The last telemetry the firmware sent (for a frame cut by a simulated reset)."""
        if self._last_tel is None:
            return m.Telemetry((0.0,) * 4, (0.0,) * 4, 0.0, 0.0, 0.0, 0.0, 0.0)
        return self._last_tel

    # ------------------------------------------------------------------ internals
    def _sensors(self) -> Sensors:
        r = self.robot
        pos, vel = r.servo_readings()
        pitch, rate = r.imu()
        return Sensors(servo_position=tuple(pos), servo_velocity=tuple(vel),
                       ina219=r.ina219_registers(), load_cell_seq=r.load_cell.seq,
                       load_cell_raw=r.load_cell.raw, winch_encoder=r.encoder(), pitch=pitch,
                       pitch_rate=rate)

    def _exchange(self, now: float, command: int, cause: int):
        # Physics up to now (a stalled caller must not turn into millions of steps).
        dt = min(now - self._last_step, 0.1)
        n = max(1, math.ceil(dt / self.config.physics_dt)) if dt > 0 else 0
        for _ in range(n):
            self.robot.step(dt / n)
        self._last_step = max(self._last_step, now)
        # At most one exchange's worth of host bytes; the rest goes in the next tick.
        rx, self._rx = bytes(self._rx[:MAX_SERIAL]), self._rx[MAX_SERIAL:]
        out = self.fw.exchange(round((now - self._t0) * 1e6), self._sensors(), rx, command,
                               cause)
        self.exchanges += 1
        r = self.robot
        r.drive(out.goal_velocity, out.winch_duty, out.winch_brake)
        r.follow(out.motion_mode, out.burrow_mode, out.unburrowing)
        for reg, value in out.ina219_writes:
            r.ina219.write(reg, value)
        self.seq = out.next_seq
        self.rx_crc_errors = out.rx_crc_errors
        self._next_due = self._boot_t + ((out.next_due_ms - self._clock0) & 0xFFFFFFFF) / 1e3
        return self._frames(out.tx)

    def _frames(self, tx: bytes) -> list[tuple[str, bytes, m.Telemetry | None]]:
        """Split the firmware's output into frames and say what each is."""
        frames = []
        for seg in tx.split(b'\x00'):
            if not seg:
                continue
            wire = b'\x00' + seg + b'\x00'
            decoded = FrameDecoder().feed(wire)
            if not decoded:    # the firmware's own output must decode: anything else is a bug
                raise FirmwareLinkError(f'the firmware wrote an undecodable frame {wire.hex()}')
            f = decoded[0]
            tel = f.message if isinstance(f.message, m.Telemetry) else None
            if tel is not None:
                self._last_tel = tel
            frames.append((_KINDS[f.message.TYPE], wire, tel))
        return frames

    def _first_frame(self, frames) -> bytes:
        if [k for k, _, _ in frames] != ['notice']:
            raise FirmwareLinkError('the firmware did not start with a RESET_NOTICE alone')
        return frames[0][1]
