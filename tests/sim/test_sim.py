"""The simulated robot and MCU firmware, without pty or ROS."""
import math

import pytest

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import FrameDecoder, encode_frame
from minirquad_sim.burrow import TABLE_II
from minirquad_sim.calibration import RATIOS, burrow_energy
from minirquad_sim.gait import BuehlerClock, wrap_angle
from minirquad_sim.ground import TableGround, slip_per_m
from minirquad_sim.mcu import McuConfig, SimMcu
from minirquad_sim.robot import SimRobot
from minirquad_sim.servo import Servo
from minirquad_sim.winch import WinchSled
from rftgls_core.types import AnchorState, Status


def test_buehler_clock_piecewise_linear():
    # MiniRHex walk: 2 s, duty 0.42, sweep 40 deg, down 20 deg toe back (-20 deg in the
    # protocol's sign). Forward: slow arc 0 -> -40 deg (toe back) in 0.84 s, then the 320 deg
    # recovery the same way round in 1.16 s.
    c = BuehlerClock(2.0, 0.42, math.radians(40), math.radians(-20))
    assert c.angle(0.0) == pytest.approx(0.0)
    assert c.angle(0.42) == pytest.approx(math.radians(-20))
    assert c.angle(0.84) == pytest.approx(math.radians(-40))
    assert c.angle(2.0) == pytest.approx(-2 * math.pi)
    assert c.ground_speed() == pytest.approx(math.radians(40) / 0.84)
    assert c.recovery_speed() == pytest.approx(math.radians(320) / 1.16)
    half = BuehlerClock(2.0, 0.42, math.radians(40), math.radians(-20), phase=0.5)
    assert half.angle(0.0) == pytest.approx(c.angle(1.0))
    # reverse: the mirror about down, toe forward in stance
    back = BuehlerClock(2.0, 0.42, math.radians(40), math.radians(-20), direction=-1)
    assert back.angle(0.84) == pytest.approx(0.0)


def test_the_walk_gait_sweeps_the_toes_back_in_stance_as_the_walk_model_does():
    """The driver's walk (gaits.py, run by the firmware's clock) and the multibody walk model
    (rftgls_core.multibody.gaits.WalkGait: theta_L falls in stance, centred on -20 deg) agree
    on the leg reference at every instant of a cycle, leg by leg: the same clock, one sign."""
    from minirquad_driver.gaits import GAITS
    from rftgls_core.multibody.gaits import WalkGait
    from rftgls_core.multibody.robot import from_preset
    from rftgls_core.robots.presets import minirquad
    g = GAITS['walk']
    body = from_preset(minirquad())
    # the driver's legs PL, PR, DL, DR by the model's leg names
    names = ('left_proximal_hip', 'right_proximal_hip', 'left_distal_hip', 'right_distal_hip')
    index = [[leg.name for leg in body.legs].index(n) for n in names]
    model = WalkGait(body, period=g.period, duty=g.duty, sweep=g.sweep, down=g.down,
                     phases={index[i]: ph for i, ph in enumerate(g.phases)})
    for t in [0.05 * k for k in range(81)]:
        q_ref, _ = model.reference(t)
        for i, ph in enumerate(g.phases):
            c = BuehlerClock(g.period, g.duty, g.sweep, g.down, ph, g.direction)
            assert wrap_angle(c.angle(t) - q_ref[index[i]]) == pytest.approx(0.0, abs=1e-9)


def test_wrap_angle_range():
    assert wrap_angle(math.pi) == pytest.approx(math.pi)
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_servo_respects_its_speed_limit():
    s = Servo(target=1.0, max_speed=2.0)
    for _ in range(10):
        s.step(0.01)
    assert s.angle == pytest.approx(0.2)
    for _ in range(200):
        s.step(0.01)
    assert s.angle == pytest.approx(1.0)


@pytest.mark.parametrize('mode', ['DH', 'DL', 'SH'])
def test_burrow_reaches_table_ii(mode):
    robot = SimRobot()
    robot.burrow(m.BurrowMode[mode])
    seen = set()
    for _ in range(800):
        robot.step(0.01)
        seen.add(robot.mode)
    seq = TABLE_II[mode]
    assert m.Mode.BURROW_RETRACT in seen and m.Mode.BURROW_FINAL in seen
    assert robot.mode == m.Mode.ANCHORED
    a = robot.leg_angles()
    assert a[0] == pytest.approx(seq.final[0], abs=math.radians(0.5))
    assert a[2] == pytest.approx(seq.final[1], abs=math.radians(0.5))
    assert robot.h == pytest.approx(seq.h, abs=1e-3)
    assert robot.theta_b == pytest.approx(seq.theta_b, abs=math.radians(0.3))


def test_burrow_energy_ratios_match_the_paper():
    # Paper section VI-B: DH and DL use 1.32x and 1.26x the energy of SH (8 s, idle removed).
    e = {mode: burrow_energy(mode) for mode in ('DH', 'DL', 'SH')}
    for mode, ratio in RATIOS.items():
        assert e[mode] / e['SH'] == pytest.approx(ratio, rel=0.01)


def _tug(mode, sled_mass, seconds=6.0):
    robot = SimRobot(winch=WinchSled(sled_mass=sled_mass))
    robot.burrow(m.BurrowMode[mode])
    for _ in range(800):
        robot.step(0.01)
    sled0, x0 = robot.winch.sled_x, robot.x_p
    robot.set_winch(0.02)
    slipped = False
    for _ in range(int(seconds / 0.01)):
        robot.step(0.01)
        slipped |= robot.slipping
    return robot.winch.sled_x - sled0, robot.x_p - x0, slipped, robot


def test_dh_tugs_a_600_g_sled():
    sled_moved, robot_moved, slipped, _ = _tug('DH', 0.600)
    assert sled_moved > 0.05 and not slipped and robot_moved == 0.0


def test_sh_slips_under_a_600_g_sled_and_the_sled_stops():
    # RFT-GLS ground (shipped MiniRQuad map): SH holds ~2.3 N, the 600 g sled needs 2.9 N.
    robot = SimRobot(winch=WinchSled(sled_mass=0.600))
    robot.burrow(m.BurrowMode.SH)
    for _ in range(800):
        robot.step(0.01)
    sled0, x0 = robot.winch.sled_x, robot.x_p
    robot.set_winch(0.02)
    for _ in range(600):
        robot.step(0.01)
        if robot.slipping:
            break
    assert robot.slipping, 'the SH anchor should fail before the 600 g sled moves'
    assert robot.winch.tension < robot.winch.sled_friction       # the sled stays put
    assert robot.winch.sled_x - sled0 < 0.005
    # While the tension stays above the capacity, p is dragged back toward the sled.
    for _ in range(100):
        robot.step(0.01)
    assert robot.x_p - x0 < -0.002


def test_sh_tugs_a_400_g_sled():
    sled_moved, _, slipped, _ = _tug('SH', 0.400)
    assert sled_moved > 0.05 and not slipped


def test_placeholder_ground_statuses():
    g = TableGround()
    bad = g.predict(AnchorState(float('nan'), 0, 0, 0), 0.0, 'backward')
    assert bad.status == Status.INVALID_INPUT and bad.capacity_N is None
    r = g.predict(AnchorState(0.034, 0.087, -0.698, 0.524), 0.0, 'backward')
    cap, twist, status = r.capacity_N, slip_per_m(r), r.status
    assert status == Status.OK and cap == pytest.approx(4.6, rel=0.05)
    assert math.hypot(twist[0], twist[1]) == pytest.approx(1.0)


def _frames(data):
    return [f.message for f in FrameDecoder().feed(data)]


def test_mcu_acks_dedups_retries_and_trips_the_watchdog():
    mcu = SimMcu(config=McuConfig(watchdog_s=0.5))
    cmd = encode_frame(m.Winch(0.01), 7, 0)
    first = _frames(mcu.receive(cmd, 0.01))
    assert first == [m.Ack(7, m.MsgType.WINCH, m.AckResult.OK)]
    mcu.robot.set_winch(0.0)
    again = _frames(mcu.receive(cmd, 0.02))      # a retry with the same seq
    assert again == first and mcu.robot.winch.command == 0.0   # not executed twice
    mcu.receive(encode_frame(m.Burrow(m.BurrowMode.DH), 8, 0), 0.03)
    out = []
    t = 0.03
    while t < 1.0:                                # no heartbeat for ~1 s
        t += 0.01
        out += mcu.tick(t)
    kinds = [k for k, _, _ in out]
    assert 'error' in kinds
    assert mcu.robot.watchdog and mcu.robot.mode == m.Mode.IDLE
    tel = _frames(out[-2][1] if out[-1][0] == 'power' else out[-1][1])[0]
    assert tel.flags & m.Flag.WATCHDOG_TRIPPED and tel.mode == m.Mode.WATCHDOG
    assert all(v == 0.0 for v in tel.leg_velocities)


def test_estop_refuses_motion():
    mcu = SimMcu()
    mcu.receive(encode_frame(m.EStop(True), 1, 0), 0.0)
    refused = _frames(mcu.receive(encode_frame(m.Burrow(m.BurrowMode.SH), 2, 0), 0.01))
    assert refused == [m.Ack(2, m.MsgType.BURROW, m.AckResult.ESTOPPED)]


def test_winch_deadman_stops_a_winch_whose_commands_stop():
    # The bridge's heartbeats keep the link watchdog fed even when the node that commands the
    # winch is dead: the MCU stops a non-zero winch speed that is not refreshed in time.
    mcu = SimMcu(config=McuConfig(watchdog_s=5.0, winch_deadman_s=0.3))  # (default 0.08 s)
    seq = 10
    mcu.receive(encode_frame(m.Winch(0.02), seq, 0), 0.0)
    out, t = [], 0.0
    while t < 1.0:                          # refreshed every 0.1 s, heartbeats alongside
        t = round(t + 0.01, 2)
        if abs(t * 10 - round(t * 10)) < 1e-9:
            seq += 1
            mcu.receive(encode_frame(m.Winch(0.02), seq, 0), t)
            mcu.receive(encode_frame(m.Heartbeat(), seq + 1000, 0), t)
        out += mcu.tick(t)
    assert mcu.robot.winch.command == 0.02 and 'error' not in [k for k, _, _ in out]
    while t < 1.5:                          # commands stop; heartbeats go on
        t = round(t + 0.01, 2)
        mcu.receive(encode_frame(m.Heartbeat(), seq + 2000 + int(100 * t), 0), t)
        out += mcu.tick(t)
        if mcu.robot.winch.command == 0.0:
            break
    assert mcu.robot.winch.command == 0.0
    assert 1.3 - 1e-9 <= t <= 1.0 + 0.3 + 0.02   # last command at 1.0 s, deadman 0.3 s
    errors = [f for k, b, _ in out if k == 'error' for f in _frames(b)]
    assert errors and errors[0].code == m.ErrorCode.WINCH_DEADMAN
    assert not mcu.robot.watchdog           # the link itself was fine all along
