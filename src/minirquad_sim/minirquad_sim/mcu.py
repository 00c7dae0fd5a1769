"""The simulated microcontroller firmware: protocol endpoint around a ``SimRobot``.

Pure logic with an injected time: ``receive`` takes host bytes and returns reply bytes,
``tick`` advances the robot and returns the telemetry and power frames that are due. The
pty, the loop timing and the fault injection live in ``main.py`` and ``faults.py``.

Firmware behaviour it models:
- one sequence counter for every frame the MCU sends (the host counts gaps in it);
- a uint32 millisecond clock (``clock_start_ms`` lets tests start it just before the wrap);
- every host command is acked with its own seq; a retry (the same seq, type and host stamp as
  the last command of its channel) is re-acked with its first answer but not executed again,
  so the host may retry; a frame of an MCU -> host type is not acked (no ACK can name it);
- the watchdog: no valid host frame for ``watchdog_s`` stops legs and winch, sends an ERROR
  once; a later heartbeat clears the flag but does not restart motion;
- the winch deadman: a non-zero winch speed not refreshed by a WINCH command for
  ``winch_deadman_s``, or for the shorter hold the command set (the age its evidence had
  left), is set to zero (ERROR WINCH_DEADMAN once). The bridge's heartbeats keep the link
  watchdog fed even when the node that commands the winch stalls or dies, so the winch itself
  must not outlive its commands or their evidence (docs/design/tug-safety.md);
- after a reset it sends a RESET_NOTICE before anything else.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from minirquad_driver import ina219
from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

from .robot import SimRobot

FIRMWARE_VERSION = 100


@dataclass
class McuConfig:
    telemetry_hz: int = 100
    power_hz: int = 50
    watchdog_s: float = 0.5
    winch_deadman_s: float = 0.08  # 0 switches the winch deadman off
    clock_start_ms: int = 0
    physics_dt: float = 0.002   # s; the robot is stepped in substeps of at most this


class SimMcu:
    """Frames in, frames out. ``on_telemetry(seq, t_ms, Telemetry)`` is called for every
    telemetry frame built (before any fault injection), ``on_command(now, message, result)``
    for every host command handled (not heartbeats or retries), for test records."""

    def __init__(self, robot_factory: Callable[[], SimRobot] = SimRobot,
                 config: McuConfig | None = None,
                 on_telemetry: Callable[[int, int, m.Telemetry], None] | None = None,
                 now: float = 0.0,
                 on_command: Callable[[float, object, int], None] | None = None):
        """``now``: the caller's clock (s) at power-on; all later times use the same clock."""
        self.robot_factory = robot_factory
        self.config = config or McuConfig()
        self.on_telemetry = on_telemetry
        self.on_command = on_command
        self.resets = 0
        self._boot(now, self.config.clock_start_ms)

    # ------------------------------------------------------------------ lifecycle
    def _boot(self, now: float, clock_start_ms: int) -> None:
        self.robot = self.robot_factory()
        self.decoder = FrameDecoder()
        self.seq = 0
        self._t0 = now
        self._clock0 = clock_start_ms
        self._last_step = now
        self._last_host_frame = now
        self._next_tel = now
        self._next_pow = now
        # Per channel: the last command's (seq, type, host t_ms) and its answer.
        self._last_cmd: dict[str, tuple[tuple[int, int, int], int]] = {}
        self._winch_cmd_t = now
        self._winch_hold = self.config.winch_deadman_s   # s the last WINCH may run
        self._watchdog_reported = False
        self.rx_crc_errors = 0

    def reset(self, now: float, cause: int = m.ResetCause.WATCHDOG) -> bytes:
        """Reboot: state and clock restart from zero; returns the RESET_NOTICE frame."""
        self.resets += 1
        self._boot(now, 0)
        return self.notice(now, cause)

    def close(self) -> None:
        """Nothing to release (the firmware MCU stops its process here)."""

    def notice(self, now: float, cause: int = m.ResetCause.POWER_ON) -> bytes:
        return self._frame(m.ResetNotice(m.PROTOCOL_VERSION, FIRMWARE_VERSION, int(cause),
                                         self.config.telemetry_hz, self.config.power_hz), now)

    def clock_ms(self, now: float) -> int:
        return (self._clock0 + int((now - self._t0) * 1000.0)) & 0xFFFFFFFF

    def _frame(self, msg, now: float) -> bytes:
        data = encode_frame(msg, self.seq, self.clock_ms(now))
        self.seq = (self.seq + 1) & 0xFF
        return data

    # ------------------------------------------------------------------ host -> MCU
    def receive(self, data: bytes, now: float) -> bytes:
        out = b''
        before = self.decoder.stats.crc_errors
        for frame in self.decoder.feed(data):
            self._last_host_frame = now
            out += self._handle(frame, now)
        if self.decoder.stats.crc_errors != before:
            self.rx_crc_errors = self.decoder.stats.crc_errors
        return out

    def _handle(self, frame, now: float) -> bytes:
        msg = frame.message
        robot = self.robot
        if isinstance(msg, m.Heartbeat):
            if robot.watchdog:
                robot.set_watchdog(False)
                self._watchdog_reported = False
            return self._frame(m.Ack(frame.seq, msg.TYPE, m.AckResult.OK), now)
        if int(msg.TYPE) not in m.HOST_TYPES:
            return b''   # an MCU -> host type sent the wrong way: no ack could name it
        # The host resends only the newest command of a channel, as a byte copy: the same
        # (seq, type, stamp) as that channel's last command is a retry. A newer command of
        # another channel in between does not make it new (a BURROW resent after a WINCH
        # must not restart the burrow); a new command 256 frames later with the same seq
        # differs in its stamp.
        channel = m.COMMAND_CHANNEL[msg.TYPE]
        key = (frame.seq, int(msg.TYPE), frame.t_mcu_ms)
        last = self._last_cmd.get(channel)
        if last is not None and key == last[0]:
            # A host retry of a command already executed: the same answer, no second run.
            return self._answer(frame.seq, msg, last[1], now)
        result = m.AckResult.OK
        if isinstance(msg, m.GetInfo):
            pass
        elif isinstance(msg, m.EStop):
            robot.set_estop(msg.engage)
        elif robot.estop and isinstance(msg, (m.SetLegs, m.SetGait, m.Burrow, m.Winch)):
            result = m.AckResult.ESTOPPED
        elif isinstance(msg, m.SetLegs):
            robot.set_legs(msg.targets, msg.mask)
        elif isinstance(msg, m.SetGait):
            robot.set_gait(msg.kind, msg.period, msg.duty, msg.sweep, msg.down, msg.phases,
                           msg.direction)
        elif isinstance(msg, m.Burrow):
            robot.burrow(msg.mode)
        elif isinstance(msg, m.Winch):
            robot.set_winch(msg.speed)
            self._winch_cmd_t = now
            deadman = self.config.winch_deadman_s
            self._winch_hold = min(msg.hold, deadman) if msg.hold > 0 and deadman > 0 \
                else (msg.hold or deadman)
        if (result == m.AckResult.OK and robot.watchdog
                and not isinstance(msg, (m.EStop, m.GetInfo))):
            robot.set_watchdog(False)
            self._watchdog_reported = False
        self._last_cmd[channel] = (key, result)
        if self.on_command is not None:
            self.on_command(now, msg, int(result))
        return self._answer(frame.seq, msg, result, now)

    def _answer(self, seq: int, msg, result: int, now: float) -> bytes:
        """The ACK of a command, and for GET_INFO the INFO after it."""
        out = self._frame(m.Ack(seq, msg.TYPE, result), now)
        if isinstance(msg, m.GetInfo):
            out += self._frame(m.Info(m.PROTOCOL_VERSION, FIRMWARE_VERSION,
                                      m.ResetCause.UNKNOWN, self.config.telemetry_hz,
                                      self.config.power_hz), now)
        return out

    # ------------------------------------------------------------------ MCU loop
    def tick(self, now: float) -> list[tuple[str, bytes, m.Telemetry | None]]:
        """Advance to ``now``; return due frames as (kind, bytes, telemetry-or-None)."""
        out: list[tuple[str, bytes, m.Telemetry | None]] = []
        # A stalled loop (debugger, overloaded host) must not turn into millions of steps.
        dt = min(now - self._last_step, 0.1)
        n = max(1, math.ceil(dt / self.config.physics_dt)) if dt > 0 else 0
        for _ in range(n):
            self.robot.step(dt / n)
        self._last_step = now
        if now - self._last_host_frame > self.config.watchdog_s and not self.robot.watchdog:
            self.robot.set_watchdog(True)
        if (self._winch_hold > 0 and self.robot.winch.command != 0.0
                and now - self._winch_cmd_t > self._winch_hold):
            stale_ms = int(1e3 * (now - self._winch_cmd_t))
            self.robot.set_winch(0.0)
            out.append(('error', self._frame(m.Error(m.ErrorCode.WINCH_DEADMAN,
                                                     min(stale_ms, 0xFFFF)), now), None))
        if self.robot.watchdog and not self._watchdog_reported:
            self._watchdog_reported = True
            out.append(('error', self._frame(m.Error(m.ErrorCode.HOST_WATCHDOG, 0), now), None))
        if now >= self._next_tel:
            self._next_tel = _next_due(self._next_tel, now, 1.0 / self.config.telemetry_hz)
            tel = self.telemetry()
            seq, t_ms = self.seq, self.clock_ms(now)
            out.append(('telemetry', self._frame(tel, now), tel))
            if self.on_telemetry:
                self.on_telemetry(seq, t_ms, tel)
        if self.config.power_hz > 0 and now >= self._next_pow:
            self._next_pow = _next_due(self._next_pow, now, 1.0 / self.config.power_hz)
            v, i = self.robot.power_model.bus(self.robot.power)
            out.append(('power', self._frame(ina219.registers_from(v, i), now), None))
        return out

    def telemetry(self) -> m.Telemetry:
        r = self.robot
        flags = r.flags()
        vel = []
        for s in r.servos:
            v = s.velocity
            if abs(v) > 32.767:
                flags |= m.Flag.VELOCITY_SATURATED
                v = math.copysign(32.767, v)
            vel.append(v)
        rate = max(-32.767, min(32.767, r.pitch_rate))
        return m.Telemetry(
            leg_angles=tuple(r.leg_angles()), leg_velocities=tuple(vel),
            pitch=r.theta_b, pitch_rate=rate, tension=r.winch.tension,
            spool_position=r.winch.spool_position, spool_velocity=r.winch.spool_velocity,
            mode=int(r.reported_mode()), flags=int(flags))

    def next_due(self) -> float:
        return min(self._next_tel, self._next_pow if self.config.power_hz > 0 else math.inf)


def _next_due(due: float, now: float, period: float) -> float:
    """Keep a fixed cadence; if the loop fell more than two periods behind, restart it."""
    due += period
    if due < now - 2 * period:
        due = now + period
    return due
