"""The bridge's logic, without ROS: decoded frames in, typed samples and diagnostics out.

``BridgeCore`` is fed raw serial bytes (from any thread) and returns samples ready to
publish; it builds command and heartbeat frames, tracks acks and retries, maps MCU time to
host time, integrates energy, and keeps the link statistics. The ROS node only converts
its outputs to messages.

Time: ``stamp`` values are host wall-clock seconds (ROS time) of the MCU sample: the MCU
timestamp mapped into the host clock by ``TimeSync`` with the lower bound of the clock
offset that round trips (acks) prove, so a sample that sat in a slow link or behind a
stalled host is stamped as old as it is. Until a round trip vouches for the offset,
samples are withheld (counted as ``unsynced_samples``). The age of every sample when it is
handed out (``delay``) and the frames lost are windowed and graded on diagnostics.
See docs/design/serial-time.md.
"""
from __future__ import annotations

import math
import statistics
import threading
import time
from collections import deque
from dataclasses import dataclass, field

from rftgls_node_base.diagnostics import DiagStatus

from . import ina219
from .energy import EnergyIntegrator
from .mcu_clock import McuClock
from .protocol import messages as m
from .protocol.codec import FrameDecoder, encode_frame
from .time_sync import TimeSync

MAX_TENSION_N = 200.0   # beyond this a reading is a fault, not a rope


@dataclass(frozen=True)
class BridgeConfig:
    """r_shunt: INA219 shunt, ohm. stale_timeout: s without telemetry before outputs are
    stale. ack_timeout: s before a command is resent; max_retries: resends before giving
    up.
    energy_max_gap: s; never integrate across a longer hole. clock_drift: s/s the
    MCU-to-host offset may move (the crystals and the host wall clock's slew: time daemons
    slew it, docs/design/serial-time.md); sync_window: s a clock bound is
    kept. diag_window: s over which delay and loss are graded. delay_warn/delay_error: s,
    the oldest sample age at hand-out in the window that makes the time status WARN/ERROR.
    loss_warn/loss_error: fraction of MCU frames lost in the window (sequence gaps) that
    makes the link status WARN/ERROR; at loss_error the link is also untrusted
    (``link_state``), counted over the shorter trust_window (s) so that a consumer stops
    within a fraction of a second of the loss starting."""

    r_shunt: float = ina219.DEFAULT_SHUNT_OHM
    stale_timeout: float = 0.25
    ack_timeout: float = 0.15
    max_retries: int = 3
    energy_max_gap: float = 0.5
    clock_drift: float = 5e-3
    sync_window: float = 10.0
    diag_window: float = 5.0
    delay_warn: float = 0.1
    delay_error: float = 0.3
    loss_warn: float = 0.02
    loss_error: float = 0.10
    trust_window: float = 1.0


@dataclass(frozen=True)
class TelemetrySample:
    """stamp: host time s; t_mcu_ms: raw MCU stamp; telemetry: SI values (see messages);
    leg_turns: whole revolutions of each leg since the link came up (unwrapped odometry)."""

    stamp: float
    t_mcu_ms: int
    telemetry: m.Telemetry
    leg_turns: tuple[int, int, int, int]


@dataclass(frozen=True)
class PowerSample:
    """stamp: host time s; reading: SI INA219 values; energy: J integrated since start."""

    stamp: float
    t_mcu_ms: int
    reading: ina219.PowerReading
    energy: float


@dataclass(frozen=True)
class CommandResult:
    """Outcome of a host command: acked with ``result`` or timed out (result None)."""

    seq: int
    type: int
    result: int | None


def winch_command(speed: float, valid_until: float, now: float) -> m.Winch:
    """The WINCH frame for a commanded speed (m/s) whose evidence runs out at ``valid_until``
    (host wall time, s; 0: no limit of its own) when sent at ``now``: the time left as its
    hold, whole milliseconds rounded down (never longer than the evidence), at most the wire's
    65.535 s. A moving speed whose evidence has already run out is sent as a brake."""
    if valid_until <= 0.0:
        return m.Winch(speed)
    left = valid_until - now
    if left < 1e-3:
        return m.Winch(0.0)
    # Wall times near 1.7e9 s carry 2.4e-7 s steps, so `left` may lie up to ~5e-7 s below the
    # whole millisecond it stands for: 1 us of slack keeps 30 ms from becoming 29.
    return m.Winch(speed, min(math.floor(left * 1e3 + 1e-3), 0xFFFF) / 1e3)


@dataclass
class _Pending:
    frame: bytes
    type: int
    sent_at: float
    sent_wall: float       # host wall time of the FIRST send: any ack answers a later copy
    tries: int = 1
    resend: bool = True    # False: a copy sent later would not mean the same (a winch hold)
    channel: str = ''      # messages.COMMAND_CHANNEL: what it sets on the MCU
    superseded: bool = False   # a newer command of its channel went out: never resent


@dataclass
class LinkCounters:
    telemetry: int = 0
    power: int = 0
    dropped_frames: int = 0       # MCU seq gaps (frames that never arrived intact)
    gap_events: int = 0
    resets: int = 0
    reset_notices: int = 0
    invalid_values: int = 0
    unsynced_samples: int = 0     # decoded but withheld: no round trip vouches for the clock
    mcu_errors: int = 0
    commands_sent: int = 0
    commands_acked: int = 0
    commands_rejected: int = 0
    command_retries: int = 0
    command_timeouts: int = 0
    commands_superseded: int = 0  # unacked, and replaced by a newer one before a resend
    heartbeats: int = 0
    unmatched_acks: int = 0
    rtt: deque = field(default_factory=lambda: deque(maxlen=200))


class BridgeCore:
    def __init__(self, config: BridgeConfig | None = None, mono=time.monotonic,
                 wall=time.time):
        self.config = config or BridgeConfig()
        self.mono = mono
        self.wall = wall
        self.sync = TimeSync(drift=self.config.clock_drift, window=self.config.sync_window)
        self.last_stamp: float | None = None            # host s of the newest telemetry
        self._delays: deque = deque()                   # (mono at hand-out, age s)
        self._snapshots: deque = deque()                # (mono, counter totals)
        self._trust_marks: deque = deque()              # (mono, frames, dropped)
        self.open_error: str | None = None              # why the port cannot be opened
        self.decoder = FrameDecoder()
        self.clock = McuClock()
        self.energy = EnergyIntegrator(max_gap_s=self.config.energy_max_gap)
        self.counters = LinkCounters()
        self.connected = False
        self.last_telemetry: m.Telemetry | None = None
        self.last_telemetry_at: float | None = None     # monotonic
        self.last_power: ina219.PowerReading | None = None
        self.about: m.ResetNotice | m.Info | None = None
        self.last_error: m.Error | None = None
        self.ina219_resets = 0
        self._lock = threading.RLock()
        self._host_seq = 0
        self._pending: dict[int, _Pending] = {}
        self._hb_sent: dict[int, tuple[float, float]] = {}   # seq -> (mono, wall)
        self._last_seq: int | None = None
        self._prev_angles: list[float] | None = None
        self._turns = [0, 0, 0, 0]
        self._rate_window: deque = deque(maxlen=400)

    # ------------------------------------------------------------------ link events
    def on_connection(self, connected: bool) -> None:
        """Called by the transport. Everything tied to the old byte stream is forgotten."""
        with self._lock:
            self.connected = connected
            self.decoder.reset()
            self._last_seq = None
            self.clock.restart()
            self.energy.mark_discontinuity()
            self.sync.reset()
            self._hb_sent.clear()
            self._trust_marks.clear()
            if connected:
                self.open_error = None

    def on_open_error(self, reason: str) -> None:
        """The transport could not open the port (it retries); shown on diagnostics."""
        with self._lock:
            self.open_error = reason

    def is_stale(self) -> bool:
        """True when the newest telemetry handed out is older than stale_timeout by its
        stamp (the sample time), whether it stopped coming or comes late."""
        with self._lock:
            if not self.connected or self.last_stamp is None:
                return True
            return self.wall() - self.last_stamp > self.config.stale_timeout

    def link_state(self) -> tuple[str, float]:
        """('stale' | 'untrusted' | 'ok', loss ratio over the last trust_window s). Stale
        wins; untrusted when at least loss_error of the MCU's frames were lost (sequence gaps,
        a frame that failed its CRC included): the samples that do arrive are intact, but a
        link losing that much is not one to act on (docs/design/serial-time.md). Call it
        periodically: each call marks the counters."""
        with self._lock:
            now, cfg = self.mono(), self.config
            q = self._trust_marks
            q.append((now, self.decoder.stats.frames, self.counters.dropped_frames))
            while len(q) > 2 and now - q[1][0] >= cfg.trust_window:
                q.popleft()
            frames, dropped = q[-1][1] - q[0][1], q[-1][2] - q[0][2]
            loss = dropped / (frames + dropped) if frames + dropped else 0.0
            if self.is_stale():
                return 'stale', loss
            return ('untrusted' if loss >= cfg.loss_error else 'ok'), loss

    # ------------------------------------------------------------------ MCU -> host
    def on_bytes(self, data: bytes, host_time: float) -> list:
        """Decode ``data`` (arrived at wall time ``host_time``); return samples to publish
        (TelemetrySample, PowerSample, CommandResult) in arrival order."""
        out = []
        with self._lock:
            for frame in self.decoder.feed(data):
                out.extend(self._on_frame(frame, host_time))
        return out

    def _on_frame(self, frame, host_time: float) -> list:
        msg = frame.message
        c = self.counters
        if isinstance(msg, m.ResetNotice):
            c.reset_notices += 1
            if self._last_seq is not None:
                c.resets += 1
            self.about = msg
            self.clock.restart()
            self.clock.update(frame.t_mcu_ms)
            self._restart_baselines()
            self._last_seq = frame.seq
            return []
        had_base = self.clock.last_raw is not None
        _, new_base = self.clock.update(frame.t_mcu_ms)
        if had_base and new_base:
            # The MCU clock went backwards without a reset notice (the notice was lost):
            # a reset all the same. Its sequence numbers restarted too, so no gap count.
            c.resets += 1
            self._restart_baselines()
        elif self._last_seq is not None:
            # Sequence gaps: frames that never arrived intact.
            gap = (frame.seq - self._last_seq - 1) & 0xFF
            if gap:
                c.dropped_frames += gap
                c.gap_events += 1
        self._last_seq = frame.seq
        mcu_s = self.clock.unwrapped_ms * 1e-3
        self.sync.add_arrival(host_time, mcu_s)
        if isinstance(msg, m.Ack):
            return self._on_ack(msg, mcu_s)
        if isinstance(msg, m.Telemetry):
            if not self._valid(msg):
                c.invalid_values += 1
                return []
            self._count_turns(msg.leg_angles)
            stamp = self._stamp(mcu_s)
            if stamp is None:
                c.unsynced_samples += 1
                return []
            c.telemetry += 1
            self.last_telemetry = msg
            self.last_telemetry_at = self.mono()
            self.last_stamp = stamp
            self._rate_window.append(self.last_telemetry_at)
            return [TelemetrySample(stamp, frame.t_mcu_ms, msg, tuple(self._turns))]
        if isinstance(msg, m.Power):
            reading = ina219.reading_from(msg, self.config.r_shunt)
            if reading.chip_reset:
                self.ina219_resets += 1
            self.last_power = reading
            # Energy is integrated on MCU time, so it needs no host stamp.
            energy = self.energy.add(frame.t_mcu_ms, reading.power)
            stamp = self._stamp(mcu_s)
            if stamp is None:
                c.unsynced_samples += 1
                return []
            c.power += 1
            return [PowerSample(stamp, frame.t_mcu_ms, reading, energy)]
        if isinstance(msg, m.Info):
            self.about = msg
        elif isinstance(msg, m.Error):
            c.mcu_errors += 1
            self.last_error = msg
        return []

    def _restart_baselines(self) -> None:
        """A new MCU time base: keep the energy, restart every baseline built on time."""
        self.energy.mark_discontinuity()
        self.sync.reset()
        self._prev_angles = None

    def _valid(self, tel: m.Telemetry) -> bool:
        # Mode and flags were range-checked by the decoder.
        return abs(tel.tension) <= MAX_TENSION_N and all(
            math.isfinite(v) for v in (*tel.leg_angles, *tel.leg_velocities, tel.pitch))

    def _count_turns(self, angles) -> None:
        if self._prev_angles is not None:
            for i, (a, b) in enumerate(zip(self._prev_angles, angles)):
                d = b - a
                if d < -math.pi:
                    self._turns[i] += 1
                elif d > math.pi:
                    self._turns[i] -= 1
        self._prev_angles = list(angles)

    def _stamp(self, mcu_s: float) -> float | None:
        """Host time of an MCU sample (None if unsynced); records its age at hand-out."""
        wall = self.wall()
        stamp = self.sync.to_host(mcu_s, wall)
        if stamp is not None:
            now = self.mono()
            self._delays.append((now, wall - stamp))
            while now - self._delays[0][0] > self.config.diag_window:
                self._delays.popleft()
        return stamp

    def _on_ack(self, ack: m.Ack, reply_mcu_s: float) -> list:
        c = self.counters
        now = self.mono()
        if ack.acked_type == m.MsgType.HEARTBEAT:
            sent = self._hb_sent.pop(ack.acked_seq, None)
            if sent is None:
                c.unmatched_acks += 1
            else:
                c.rtt.append(now - sent[0])
                self.sync.add_round_trip(sent[1], reply_mcu_s)
            return []
        pend = self._pending.get(ack.acked_seq)
        if pend is None or pend.type != ack.acked_type:
            c.unmatched_acks += 1     # a late ack for a command already resolved
            return []
        del self._pending[ack.acked_seq]
        self.sync.add_round_trip(pend.sent_wall, reply_mcu_s)
        if pend.tries == 1:
            c.rtt.append(now - pend.sent_at)
        if ack.result == m.AckResult.OK:
            c.commands_acked += 1
        else:
            c.commands_rejected += 1
        return [CommandResult(ack.acked_seq, ack.acked_type, ack.result)]

    # ------------------------------------------------------------------ host -> MCU
    def _next_seq(self) -> int:
        s = self._host_seq
        self._host_seq = (s + 1) & 0xFF
        return s

    def heartbeat(self) -> bytes:
        with self._lock:
            seq = self._next_seq()
            self._hb_sent[seq] = (self.mono(), self.wall())
            # Forget heartbeats that were never answered, keeping the table small.
            if len(self._hb_sent) > 64:
                for k in sorted(self._hb_sent, key=self._hb_sent.get)[:32]:
                    del self._hb_sent[k]
            self.counters.heartbeats += 1
            return encode_frame(m.Heartbeat(), seq, self._host_ms())

    def command(self, msg) -> bytes:
        """Frame for a host command; raises ValueError for values the wire cannot carry."""
        with self._lock:
            msg.pack()   # raises ValueError before a sequence number is spent
            seq = self._next_seq()
            frame = encode_frame(msg, seq, self._host_ms())
            # A hold counts from the MCU's receipt: resent 0.15 s later it would run the winch
            # that much past its evidence. The commander refreshes it instead.
            resend = int(msg.TYPE) in m.IDEMPOTENT_COMMANDS \
                and not (isinstance(msg, m.Winch) and msg.hold > 0)
            # The MCU executes a resent frame again unless it is the last one it received,
            # so a copy of an older command resent after this one would undo it (a stand
            # lost on the wire, resent after the burrow that followed it, stands the robot
            # out of its burrow). Older commands of this channel are never resent; their
            # acks are still matched.
            channel = m.COMMAND_CHANNEL[msg.TYPE]
            for p in self._pending.values():
                if p.channel == channel:
                    p.superseded = True
            self._pending[seq] = _Pending(frame, int(msg.TYPE), self.mono(), self.wall(),
                                          resend=resend, channel=channel)
            self.counters.commands_sent += 1
            return frame

    def awaiting_ack(self, msg_type: int) -> bool:
        """True while the newest command of this type (m.MsgType) is sent and not yet
        acknowledged (nor given up on)."""
        with self._lock:
            return any(p.type == int(msg_type) and not p.superseded
                       for p in self._pending.values())

    def due_retries(self) -> tuple[list[bytes], list[CommandResult]]:
        """Frames to resend now, and commands given up on (result None)."""
        resend, failed = [], []
        with self._lock:
            now = self.mono()
            for seq, p in list(self._pending.items()):
                if now - p.sent_at < self.config.ack_timeout:
                    continue
                if p.superseded:            # the newer command is what counts now
                    del self._pending[seq]
                    self.counters.commands_superseded += 1
                    continue
                if p.tries > self.config.max_retries or not p.resend:
                    del self._pending[seq]
                    self.counters.command_timeouts += 1
                    failed.append(CommandResult(seq, p.type, None))
                    continue
                p.tries += 1
                p.sent_at = now
                self.counters.command_retries += 1
                resend.append(p.frame)   # same seq: the MCU re-acks without re-executing
        return resend, failed

    def _host_ms(self) -> int:
        return int(self.mono() * 1000.0) & 0xFFFFFFFF

    # ------------------------------------------------------------------ diagnostics
    def telemetry_rate(self, window: float = 1.0) -> float:
        with self._lock:
            now = self.mono()
            n = sum(1 for t in self._rate_window if now - t <= window)
            return n / window

    def _windowed(self, totals: dict) -> dict:
        """Change of each counter over about the last diag_window seconds (since start
        when younger), from snapshots taken at each diagnostics call."""
        now = self.mono()
        q = self._snapshots
        if not q:
            q.append((now, dict.fromkeys(totals, 0)))
        q.append((now, dict(totals)))
        while len(q) > 2 and now - q[1][0] >= self.config.diag_window:
            q.popleft()
        base = q[0][1]
        return {k: v - base.get(k, 0) for k, v in totals.items()}

    def _time_status(self) -> DiagStatus:
        cfg = self.config
        now, wall = self.mono(), self.wall()
        ages = [a for t, a in self._delays if now - t <= cfg.diag_window]
        low = self.sync.lower(wall)
        unc = self.sync.uncertainty(wall)
        values = {
            'clock_synced': low is not None,
            'clock_offset_s': round(low, 6) if low is not None else None,
            'clock_uncertainty_ms': round(1e3 * unc, 3) if unc is not None else None,
            'round_trips': self.sync.round_trips,
            'unsynced_samples': self.counters.unsynced_samples,
            'delay_median_ms': round(1e3 * statistics.median(ages), 3) if ages else None,
            'delay_max_ms': round(1e3 * max(ages), 3) if ages else None,
            'delay_window_s': cfg.diag_window,
            'delay_warn_ms': round(1e3 * cfg.delay_warn, 3),
            'delay_error_ms': round(1e3 * cfg.delay_error, 3),
        }
        level, alarms, msg = 0, [], 'ok'
        if not self.connected:
            level, msg = 3, 'disconnected'
        elif low is None:
            level, msg = 1, 'clock not synced: samples withheld'
            alarms.append('clock_synced')
        if ages and max(ages) >= cfg.delay_warn:
            worst = max(ages)
            lvl = 2 if worst >= cfg.delay_error else 1
            alarms.append('delay_max_ms')
            if lvl > level or level == 0:
                msg = f'samples up to {1e3 * worst:.0f} ms old when published'
            level = max(level, lvl)
        values['alarms'] = ','.join(alarms)
        return DiagStatus('minirquad_driver: time', level, msg, values)

    def diagnostics(self, port: str = '', transport=None) -> list[DiagStatus]:
        with self._lock:
            c, d = self.counters, self.decoder.stats
            stale = self.is_stale()
            rtt = list(c.rtt)
            cfg = self.config
            win = self._windowed({'frames': d.frames, 'dropped': c.dropped_frames,
                                  'protocol_rejects': d.protocol_rejects,
                                  'version_errors': d.version_errors})
            expected = win['frames'] + win['dropped']
            loss = win['dropped'] / expected if expected else 0.0
            link_values = {
                'port': port, 'connected': self.connected,
                'frames': d.frames, 'bytes_in': d.bytes_in,
                'telemetry_frames': c.telemetry, 'power_frames': c.power,
                'telemetry_rate_hz': round(self.telemetry_rate(), 1),
                'crc_errors': d.crc_errors, 'cobs_errors': d.cobs_errors,
                'other_rejected': d.rejected - d.crc_errors - d.cobs_errors,
                'version_errors': d.version_errors, 'unknown_types': d.unknown_types,
                'other_protocol_version': d.other_version,
                'range_errors': d.range_errors, 'payload_errors': d.payload_errors,
                'protocol_rejects': d.protocol_rejects,
                'protocol_rejects_window': win['protocol_rejects'],
                'dropped_frames': c.dropped_frames, 'gap_events': c.gap_events,
                'loss_ratio': round(loss, 4), 'loss_window_s': cfg.diag_window,
                'loss_warn': cfg.loss_warn, 'loss_error': cfg.loss_error,
                'open_error': self.open_error,
                'invalid_values': c.invalid_values,
                'mcu_resets': c.resets, 'reset_notices': c.reset_notices,
                'clock_wraps': self.clock.wraps,
                'rtt_median_ms': round(1e3 * statistics.median(rtt), 3) if rtt else None,
                'rtt_max_ms': round(1e3 * max(rtt), 3) if rtt else None,
            }
            if transport is not None:
                s = transport.stats
                link_values.update(reconnects=s.reconnects, disconnects=s.disconnects,
                                   open_failures=s.open_failures,
                                   silence_reconnects=s.silence_reconnects,
                                   write_errors=s.write_errors)
            level, msg, alarms = 0, 'ok', []
            if not self.connected and self.open_error:
                level, msg = 2, f'cannot open port: {self.open_error}'
                alarms.append('open_error')
            elif not self.connected:
                level, msg = 3, 'disconnected'
            elif stale:
                level, msg = 3, 'stale: no fresh telemetry'
            if loss >= cfg.loss_warn:
                alarms.append('loss_ratio')
                if level == 0:
                    msg = f'{100 * loss:.1f} % of frames lost'
                level = max(level, 2 if loss >= cfg.loss_error else 1)
            if win['protocol_rejects']:
                alarms.append('protocol_rejects')
                if level == 0:
                    msg = 'frames with fields this protocol does not define'
                level = max(level, 1)
            if win['version_errors'] and d.other_version is not None:
                # The cause of a link that stays stale however good the wire: name it.
                alarms.append('protocol_version')
                msg = (f'the MCU speaks protocol version {d.other_version}, this bridge '
                       f'{m.PROTOCOL_VERSION}: flash the firmware that goes with this host')
                level = max(level, 2)
            link_values['alarms'] = ','.join(alarms)
            link = DiagStatus('minirquad_driver: link', level, msg, link_values)
            cmd = DiagStatus('minirquad_driver: commands',
                             1 if c.command_timeouts else 0,
                             'ok' if not c.command_timeouts else 'command timeouts', {
                                 'sent': c.commands_sent, 'acked': c.commands_acked,
                                 'rejected': c.commands_rejected,
                                 'retries': c.command_retries,
                                 'timeouts': c.command_timeouts,
                                 'superseded': c.commands_superseded,
                                 'heartbeats': c.heartbeats,
                                 'unmatched_acks': c.unmatched_acks})
            e = self.energy
            p = self.last_power
            power = DiagStatus('minirquad_driver: power', 3 if stale else 0,
                               'stale' if stale else 'ok', {
                                   'energy_j': round(e.energy_j, 6),
                                   'integrated_s': round(e.integrated_s, 3),
                                   'missing_s': round(e.missing_s, 3),
                                   'energy_gaps': e.gaps, 'energy_resets': e.resets,
                                   'ina219_chip_resets': self.ina219_resets,
                                   'bus_voltage_v': p.bus_voltage if p else None,
                                   'current_a': p.current if p else None})
            tel = self.last_telemetry
            flags = m.Flag(tel.flags) if tel else m.Flag(0)
            watchdog = bool(flags & m.Flag.WATCHDOG_TRIPPED)
            mcu_level = 3 if stale else (1 if watchdog or flags & m.Flag.ESTOP else 0)
            mcu = DiagStatus('minirquad_driver: mcu', mcu_level,
                             'stale' if stale else ('watchdog tripped' if watchdog else 'ok'), {
                                 'mode': m.Mode(tel.mode).name if tel else None,
                                 'flags': str(flags.name) if flags else '',
                                 'firmware_version': self.about.firmware_version
                                 if self.about else None,
                                 'protocol_version': self.about.protocol_version
                                 if self.about else None,
                                 'mcu_errors': c.mcu_errors,
                                 'last_error': m.ErrorCode(self.last_error.code).name
                                 if self.last_error and self.last_error.code
                                 in tuple(m.ErrorCode) else None,
                                 'leg_turns': list(self._turns)})
            return [link, self._time_status(), cmd, power, mcu]
