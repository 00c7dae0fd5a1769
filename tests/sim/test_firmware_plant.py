"""The compiled firmware against the simulated plant's faults, in lockstep: what only the
firmware models (the INA219 calibration, the load cell, the winch motor's stall), and how
the simulator refuses a firmware it cannot trust."""
from __future__ import annotations

import subprocess
import sys

import pytest
from test_mcu_contract import Bench

from minirquad_driver.protocol import messages as m
from minirquad_sim.firmware_link import FirmwareLinkError
from minirquad_sim.firmware_mcu import FirmwareMcu
from minirquad_sim.ground import TableGround
from minirquad_sim.plant import PlantRobot, RobotBuild
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import Status

pytestmark = pytest.mark.usefixtures('firmware_build')


@pytest.fixture
def bench():
    made = []

    def make(**config):
        b = Bench('firmware', **config)
        made.append(b)
        return b

    yield make
    for b in made:
        b.close()


def test_ina219_brown_out_is_reported_once_then_restored(bench):
    b = bench()
    b.run(0.2)
    assert b.of(m.Power)[-1][1].message.cal == 4096
    assert b.mcu.robot.ina219.config == 0x39E7          # written by the firmware at boot
    b.mcu.robot.ina219.reset()                          # a load spike browns the chip out
    b.run(0.2)
    cals = [f.message.cal for t, f in b.of(m.Power) if t > 0.2]
    assert cals.count(0) == 1 and cals[-1] == 4096
    zero = [f.message for t, f in b.of(m.Power) if t > 0.2 and f.message.cal == 0][0]
    assert zero.current == 0 and zero.power == 0 and zero.shunt > 0   # host uses shunt / R


def test_load_cell_silence_invalidates_tension_and_refuses_reel_in(bench):
    b = bench()
    b.run(0.1)
    assert not b.last_telemetry().flags & m.Flag.TENSION_INVALID
    b.mcu.robot.load_cell.silent = True
    b.run(0.1)
    tel = b.last_telemetry()
    assert tel.flags & m.Flag.TENSION_INVALID
    assert [f.message.code for _, f in b.of(m.Error)] == [m.ErrorCode.WINCH_SENSOR]
    s = b.send(m.Winch(0.02))
    assert b.acks()[-1] == m.Ack(s, m.MsgType.WINCH, m.AckResult.BUSY)
    b.run(0.1, winch=0.02)
    assert b.mcu.robot.winch.spool_velocity == 0.0
    b.send(m.Winch(-0.02))                              # paying out stays allowed
    b.run(0.05)
    assert b.mcu.robot.winch.spool_velocity < 0
    b.mcu.robot.load_cell.silent = False
    b.run(0.1, winch=0.0)
    assert not b.last_telemetry().flags & m.Flag.TENSION_INVALID


class _Rock(TableGround):
    """An anchor that never slips: the winch can only stall against it."""

    def predict(self, state, phi, pull='backward'):
        return CapacityResult(phi=phi, status=Status.OK, method='rock', capacity_N=100.0,
                              slip_twist=(1.0, 0.0, 0.0))


def test_winch_stall_against_a_fixed_sled_is_detected_and_latched(bench):
    b = bench()
    b.mcu.robot.ground = _Rock()
    b.mcu.robot.winch.sled_mu = 50.0                    # a sled that will not move
    b.run(0.05)
    b.run(20.0, winch=0.05, until=lambda: bool(b.of(m.Error)))
    errors = [f.message for _, f in b.of(m.Error)]
    assert [e.code for e in errors] == [m.ErrorCode.WINCH_STALL]
    # Full drive stops the spool at 8 N (plant.MotorWinch); the firmware calls it a stall
    # below 2 mm/s, reached at 8 N x (1 - 2 / 80) = 7.8 N, and reports the load cell's
    # reading then (4.7 uN per count).
    assert 7800 - 5 <= errors[0].detail <= 8000 + 5
    b.run(0.1, winch=0.05)
    assert b.last_telemetry().flags & m.Flag.WINCH_STALLED
    assert b.acks()[-1].result == m.AckResult.BUSY
    assert b.mcu.robot.winch.brake
    b.send(m.Winch(0.0))                                # the host has seen it: latch off
    s = b.send(m.Winch(-0.01))
    assert b.acks()[-1] == m.Ack(s, m.MsgType.WINCH, m.AckResult.OK)


def test_a_firmware_built_for_another_robot_is_refused():
    with pytest.raises(FirmwareLinkError, match='leg zeros'):
        FirmwareMcu(robot_factory=lambda: PlantRobot(
            ground=TableGround(), build=RobotBuild(leg_zero=(0, 0, 0, 0))))


def test_a_firmware_that_does_not_start_is_one_clear_error(tmp_path):
    fake = tmp_path / 'fw_sitl'
    fake.write_text('#!/bin/sh\nexit 3\n')
    fake.chmod(0o755)
    with pytest.raises(FirmwareLinkError, match='exited'):
        FirmwareMcu(robot_factory=lambda: PlantRobot(ground=TableGround()), binary=fake)
    r = subprocess.run([sys.executable, '-m', 'minirquad_sim.main', '--mcu', 'firmware',
                        '--firmware', str(tmp_path / 'missing'), '--ground', 'table',
                        '--duration', '0.2'], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and 'Traceback' not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and 'make setup' in r.stderr
