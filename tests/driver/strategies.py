"""Hypothesis strategies for every protocol message, within the wire ranges of
src/minirquad_driver/PROTOCOL.md."""
import math

from hypothesis import strategies as st

from minirquad_driver.protocol import messages as m

angle = st.floats(-math.pi, math.pi, allow_nan=False)
rate = st.floats(-32.0, 32.0, allow_nan=False)
big = st.floats(-2000.0, 2000.0, allow_nan=False)
u8 = st.integers(0, 255)
u16 = st.integers(0, 0xFFFF)
i16 = st.integers(-0x8000, 0x7FFF)
four = lambda s: st.tuples(s, s, s, s)  # noqa: E731

telemetry = st.builds(m.Telemetry, leg_angles=four(angle), leg_velocities=four(rate),
                      pitch=angle, pitch_rate=rate, tension=big, spool_position=big,
                      spool_velocity=st.floats(-2.0, 2.0), mode=st.sampled_from(list(m.Mode)),
                      flags=st.integers(0, m.ALL_FLAGS))
power = st.builds(m.Power, bus=u16, shunt=i16, current=i16, power=u16, cal=u16)
about = dict(protocol_version=st.just(m.PROTOCOL_VERSION), firmware_version=u16,
             reset_cause=st.sampled_from(list(m.ResetCause)), telemetry_hz=u16,
             power_hz=u16)
commands = st.one_of(
    st.builds(m.Heartbeat), st.builds(m.GetInfo),
    st.builds(m.SetLegs, targets=four(angle), mask=st.integers(0, 15)),
    st.builds(m.SetGait, kind=st.sampled_from(list(m.GaitKind)),
              period=st.floats(0.05, 65.0), duty=st.floats(0.001, 0.999),
              sweep=st.floats(1e-3, 6.28), down=angle,
              phases=four(st.floats(0.0, 0.9999)), direction=st.sampled_from([1, -1])),
    st.builds(m.Burrow, mode=st.sampled_from(list(m.BurrowMode))),
    st.builds(m.Winch, speed=st.floats(-1.0, 1.0)),
    st.builds(m.EStop, engage=st.booleans()),
)
mcu_messages = st.one_of(
    telemetry, power,
    st.builds(m.Ack, acked_seq=u8, acked_type=st.sampled_from(sorted(m.HOST_TYPES)),
              result=st.sampled_from(list(m.AckResult))),
    st.builds(m.ResetNotice, **about), st.builds(m.Info, **about),
    st.builds(m.Error, code=st.sampled_from(list(m.ErrorCode)), detail=u16),
    st.builds(m.Log, text=st.text(max_size=50)),
)
any_message = st.one_of(mcu_messages, commands)
