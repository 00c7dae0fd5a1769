"""The simulated robot on rftgls_core's whole-robot physics (``--body physics``): the MCU's
SH burrow moves the legs against the sand, and the body's pose and the electrical power
come out of the simulation, not out of the paper's Table II."""
from __future__ import annotations

import math

import pytest

from minirquad_driver.protocol.messages import BurrowMode, Mode
from minirquad_sim.burrow import TABLE_II
from minirquad_sim.physics import PhysicsBody
from minirquad_sim.robot import SimRobot

STEP = 0.002    # s, the simulator loop's step


def test_the_physics_body_burrows_and_reports_its_power():
    robot = SimRobot(physics=PhysicsBody())
    h_stand = robot.h
    robot.burrow(BurrowMode.SH)
    above_idle = 0.0
    for _ in range(round(5.0 / STEP)):
        robot.step(STEP)
        above_idle += (robot.power - robot.power_model.p_idle) * STEP
    body = robot.physics
    assert body is not None and not body.failed
    assert robot.mode is Mode.ANCHORED
    # the legs reached the final pose against the sand (the MCU's 0.5 deg arrival)
    final = TABLE_II['SH'].final
    angles = robot.leg_angles()
    for i, a in enumerate(angles):
        assert a == pytest.approx(final[0 if i < 2 else 1], abs=math.radians(1.0))
    # the pose is the physics' own: p is where the simulation put it, lower than standing
    x, z, theta_b = body.pose
    assert (robot.h, robot.theta_b) == (z, theta_b)
    assert robot.h < h_stand - 0.01
    # the electrical power above idle is the servo model's, summed over the burrow
    assert above_idle > 0.0
    assert robot.power == pytest.approx(robot.power_model.p_idle + body.elec_W
                                        + robot.power_model.winch_power(
                                            robot.winch.tension, robot.winch.spool_velocity,
                                            robot.winch.stalled))


def test_a_bad_true_medium_is_refused():
    with pytest.raises(ValueError, match='medium_scale'):
        PhysicsBody(medium_scale=float('nan'))


def test_the_drivers_walk_moves_the_physics_body_away_from_p():
    """The driver's walk gait, run by the MCU's clock on the physics body: within the first
    second (before the walk's known overturn, docs/design/walk-burrow-physics.md) the body
    moves toward +x, away from the winch point p, as the walk model's forward walk does (a
    clock that swept the toes forward in stance moved it 84 mm toward p)."""
    from minirquad_driver.gaits import GAITS
    robot = SimRobot(physics=PhysicsBody())
    g = GAITS['walk']
    robot.set_gait(int(g.kind), g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
    x0 = robot.physics.pose[0]
    for _ in range(round(1.0 / STEP)):
        robot.step(STEP)
    assert not robot.physics.failed
    assert robot.physics.pose[0] - x0 > 0.01
