"""BridgeCore without ROS, on a scripted link with known delays: the truth is built here.

A fake MCU clock runs at a known offset from the host wall clock; frames are delivered with
chosen one-way delays (MCU -> host and host -> MCU), host stalls and sequence gaps. The
tests check the contract others rely on: every stamp is the host time of the MCU sample,
never fresher than the truth and older only by what the link cannot tell apart (the
host -> MCU delay), and delay, loss and protocol violations are graded on diagnostics.
"""
from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from minirquad_driver.bridge import BridgeConfig, BridgeCore, TelemetrySample
from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame

WALL0 = 1.7e9     # host wall clock at the start of a script, s
OK, WARN, ERROR, STALE = 0, 1, 2, 3


def _tel(i: int = 0, mode: int = m.Mode.WALKING, flags: int = 0) -> m.Telemetry:
    a = 0.001 * (i % 1000)
    return m.Telemetry((a, -a, a, -a), (0.0,) * 4, 0.1, 0.0, 1.0, 0.0, 0.0, mode, flags)


class Link:
    """Host clock + MCU clock + delays; drives one BridgeCore."""

    def __init__(self, mcu0: float = 1000.0, d_up: float = 0.002, d_down: float = 0.002,
                 config: BridgeConfig | None = None, slew: float = 0.0):
        self.t = WALL0                      # host wall time now
        self.theta = WALL0 - mcu0           # host - MCU at WALL0, s
        self.slew = slew                    # s/s the host wall clock gains on the MCU's
        self.d_up, self.d_down = d_up, d_down
        self.seq = 0
        self.core = BridgeCore(config or BridgeConfig(), mono=lambda: self.t - WALL0,
                               wall=lambda: self.t)
        self.core.on_connection(True)

    def mcu_ms(self, host_t: float) -> int:
        theta = self.theta + self.slew * (host_t - WALL0)
        return int((host_t - theta) * 1000.0)           # the MCU truncates to whole ms

    def frame(self, msg, sampled_at: float) -> bytes:
        data = encode_frame(msg, self.seq, self.mcu_ms(sampled_at))
        self.seq = (self.seq + 1) & 0xFF
        return data

    def deliver(self, data: bytes, at: float) -> list:
        self.t = max(self.t, at)
        return self.core.on_bytes(data, self.t)

    def heartbeat(self) -> list:
        """Host sends a heartbeat now; the MCU acks on receipt; the ack comes back."""
        hb = FrameDecoder().feed(self.core.heartbeat())[0]
        rx = self.t + self.d_down
        ack = self.frame(m.Ack(hb.seq, m.MsgType.HEARTBEAT), rx)
        return self.deliver(ack, rx + self.d_up)

    def sample(self, i: int = 0, **kw) -> tuple[float, list]:
        """MCU samples telemetry now (host time), it arrives d_up later."""
        at = self.t
        return at, self.deliver(self.frame(_tel(i, **kw), at), at + self.d_up)

    def status(self, name: str):
        return {d.name: d for d in self.core.diagnostics()}[f'minirquad_driver: {name}']


@settings(max_examples=200)
@given(mcu0=st.floats(1.0, 4.0e6), d_up=st.floats(0.0, 0.8), d_down=st.floats(0.0, 0.3),
       period=st.floats(0.005, 0.05))
def test_stamp_is_sample_time_never_fresher_and_older_only_by_the_down_delay(
        mcu0, d_up, d_down, period):
    link = Link(mcu0, d_up, d_down)
    drift = link.core.config.clock_drift
    last_hb = link.t
    link.heartbeat()
    for i in range(40):
        link.t += period
        if i % 10 == 0:
            last_hb = link.t
            link.heartbeat()
        sampled, out = link.sample(i)
        (s,) = [x for x in out if isinstance(x, TelemetrySample)]
        assert s.stamp <= sampled + 1e-6
        # Older only by: the host -> MCU delay (indistinguishable from offset), 1 ms of
        # truncation of each MCU stamp, and the drift allowance since the round trip.
        assert s.stamp >= sampled - d_down - 2e-3 - drift * (link.t - last_hb) - 1e-6


@settings(max_examples=50, deadline=None)
@given(slew=st.floats(-5e-3, 5e-3), d_up=st.floats(0.0, 0.05), d_down=st.floats(0.0, 0.05))
def test_stamps_are_never_fresher_while_the_host_clock_is_slewed(slew, d_up, d_down):
    """The host side of the offset is the wall clock, which time daemons slew against the
    MCU's crystal (ntpd up to 500 ppm; this CI machine's wall clock was measured gaining 5 ms
    per second on its monotonic clock): over 20 s of 100 Hz samples and 10 Hz heartbeats
    with the wall clock slewed either way, no stamp is fresher than its sample."""
    link = Link(1000.0, d_up, d_down, slew=slew)
    link.heartbeat()
    for i in range(2000):
        link.t += 0.01
        if i % 10 == 0:
            link.heartbeat()
        sampled, out = link.sample(i)
        (s,) = [x for x in out if isinstance(x, TelemetrySample)]
        assert s.stamp <= sampled + 1e-6, (i, s.stamp - sampled)


def test_without_a_round_trip_samples_are_withheld_and_time_warns():
    link = Link()
    _, out = link.sample()
    assert out == []
    assert link.core.counters.unsynced_samples == 1
    time_st = link.status('time')
    assert time_st.level == WARN and 'clock_synced' in time_st.values['alarms'].split(',')
    assert link.core.is_stale()
    link.heartbeat()
    _, out = link.sample()
    assert len(out) == 1 and not link.core.is_stale()


def test_400ms_link_latency_is_in_the_stamps_and_graded_error():
    link = Link(d_up=0.4, d_down=0.0)
    drift = link.core.config.clock_drift
    last_hb, worst = link.t, 0.0
    link.heartbeat()
    for i in range(50):
        link.t += 0.01
        if i % 10 == 0:
            last_hb = link.t
            link.heartbeat()
        sampled, out = link.sample(i)
        (s,) = out
        # Older than its sample by 1 ms of truncation at each end and the drift allowance
        # since the newest round trip was sent (as in the test above).
        tol = 2e-3 + drift * (link.t - last_hb)
        assert -1e-6 <= (link.t - s.stamp) - 0.4 < tol     # 0.4 s old when handed out
        assert -tol < s.stamp - sampled <= 1e-6
        worst = max(worst, tol)
    st_time = link.status('time')
    assert st_time.level == ERROR
    assert st_time.values['alarms'] == 'delay_max_ms'
    assert 395 <= st_time.values['delay_median_ms'] <= 400 + 1e3 * worst + 1
    assert link.core.is_stale()        # the newest sample is older than stale_timeout


def test_2s_host_stall_shows_in_stamps_and_time_status():
    link = Link()
    link.heartbeat()
    for i in range(20):
        link.t += 0.01
        link.sample(i)
    assert link.status('time').level == OK
    # The host stops reading for 2 s; the MCU keeps sampling at 100 Hz into the buffer.
    backlog, t0 = [], link.t
    for i in range(200):
        at = t0 + 0.01 * (i + 1)
        backlog.append((at, link.frame(_tel(100 + i), at)))
    link.t = t0 + 2.0 + 0.01
    stamps = []
    for at, data in backlog:
        (s,) = link.deliver(data, link.t)
        stamps.append((at, s.stamp))
    # The true sample time, older only by the host -> MCU delay, 2 ms of truncation and the
    # drift allowance over the 2 s since the last round trip.
    tol = link.d_down + 2.5e-3 + link.core.config.clock_drift * 2.02
    assert all(-tol < stamp - at <= 1e-6 for at, stamp in stamps)
    assert max(link.t - stamp for _, stamp in stamps) > 1.95       # 2 s old, and shown so
    st_time = link.status('time')
    assert st_time.level == ERROR and 'delay_max_ms' in st_time.values['alarms']
    assert st_time.values['delay_max_ms'] > 1950


def test_frame_loss_is_graded_by_window():
    cfg = BridgeConfig()
    link = Link(config=cfg)
    link.heartbeat()
    for i in range(100):
        link.t += 0.01
        link.sample(i)
    assert link.status('link').level == OK
    # 38 % of the next frames never arrive (sequence gaps).
    lost = 0
    for i in range(600):
        link.t += 0.01
        if i % 10 == 0:
            link.heartbeat()
        if i % 8 in (0, 3, 5):                        # 3 of 8 never arrive: 37.5 %
            link.seq = (link.seq + 1) & 0xFF
            lost += 1
        else:
            link.sample(i)
        if i % 50 == 0:
            link.core.diagnostics()                    # the node does this every period
    st_link = link.status('link')
    assert st_link.level == ERROR and 'loss_ratio' in st_link.values['alarms']
    assert 0.30 <= st_link.values['loss_ratio'] <= 0.40
    assert link.core.counters.dropped_frames == lost
    # Once the loss stops, the window forgets it.
    for i in range(700):
        link.t += 0.01
        if i % 10 == 0:
            link.heartbeat()
        link.sample(i)
        if i % 50 == 0:
            link.core.diagnostics()                    # the node does this every period
    assert link.status('link').level == OK


def test_undefined_protocol_fields_are_rejected_counted_and_shown():
    link = Link()
    link.heartbeat()
    bad = [
        _tel(mode=9),                                        # no such mode
        _tel(flags=0x8000),                                  # reserved flag bit
        m.Ack(0, m.MsgType.HEARTBEAT, 9),                    # no such result code
        m.Ack(0, m.MsgType.TELEMETRY, 0),                    # acks a type the host never sends
        m.Info(m.PROTOCOL_VERSION + 1, 1, 0, 100, 50),       # another protocol version inside
        m.ResetNotice(m.PROTOCOL_VERSION, 1, 77, 100, 50),  # no such reset cause
        m.Error(99, 0),                                      # no such error code
    ]
    for msg in bad:
        link.t += 0.01
        assert link.deliver(link.frame(msg, link.t), link.t) == []
    link.t += 0.01
    assert link.deliver(encode_frame(_tel(), link.seq, link.mcu_ms(link.t),
                                     version=m.PROTOCOL_VERSION + 1), link.t) == []
    d = link.core.decoder.stats
    assert d.range_errors == len(bad) and d.version_errors == 1
    assert link.core.about is None and link.core.last_error is None
    st_link = link.status('link')
    assert st_link.level >= WARN and 'protocol_rejects' in st_link.values['alarms']
    assert st_link.values['protocol_rejects'] == len(bad) + 1


def test_an_mcu_of_another_protocol_version_is_named_not_just_stale():
    """Firmware built for protocol version 1 (WINCH without its hold) on a version-2 host:
    every intact frame is dropped, nothing is published, and the link status says which
    version the MCU speaks rather than only 'stale'."""
    link = Link()
    old = m.PROTOCOL_VERSION - 1
    for i in range(50):                       # 0.5 s of telemetry and heartbeat acks
        link.t += 0.01
        assert link.deliver(encode_frame(_tel(i), i, link.mcu_ms(link.t), version=old),
                            link.t) == []
    assert link.core.decoder.stats.version_errors == 50 and link.core.is_stale()
    st = link.status('link')
    assert st.level >= ERROR and 'protocol_version' in st.values['alarms'], st
    assert f'speaks protocol version {old}, this bridge {m.PROTOCOL_VERSION}' in st.message
    assert st.values['other_protocol_version'] == old


def test_reset_restarts_the_clock_mapping():
    link = Link()
    link.heartbeat()
    link.t += 0.01
    assert len(link.sample()[1]) == 1
    # The MCU reboots: its clock restarts near zero; old bounds must not be used.
    link.theta = link.t - 0.5
    link.seq = 0
    notice = m.ResetNotice(m.PROTOCOL_VERSION, 1, m.ResetCause.WATCHDOG, 100, 50)
    link.deliver(link.frame(notice, link.t), link.t)
    link.t += 0.01
    assert link.sample()[1] == []                     # withheld until a new round trip
    link.heartbeat()
    link.t += 0.01
    sampled, out = link.sample()
    assert abs(out[0].stamp - sampled) < 5e-3
