"""Why behavior_node steps off before a re-burrow (behavior/walk.py, STEP_OFF), measured on the
simulator's physics body (``--body burrow-physics``, as in ``make demo``): a planned gait
burrowed where an earlier burrow dug ends at another pose than from a fresh start, and after
a walk it ends where a fresh start does. The 600 g sled of the demo, the rope taken up to
1 N before each burrow (behavior_node's take-up), the legs streamed every 20 ms along the
gait's ramp as behavior_node streams them (gait_motion.gait_targets, from the legs' pose
through standing)."""
from __future__ import annotations

import math

import pytest

from minirquad_driver.gaits import GAITS
from minirquad_sim.physics import PhysicsBody
from minirquad_sim.robot import SimRobot
from minirquad_sim.winch import WinchSled
from rftgls_ros.behavior.gait_motion import gait_duration, gait_targets

STEP = 0.002        # s, the simulator loop's step
STREAM = 0.02       # s, behavior_node's step
SPEED = 1.0         # rad/s, the gaits' slew
D = math.radians
# (retract, final), rad: the gaits the demo's 600 g sled burrowed in one cycle that stopped
FIRST = ((D(-60), D(-20)), (D(-20), D(0)))
AGAIN = ((D(-60), D(-20)), (D(-40), D(-20)))


def run(robot: SimRobot, seconds: float) -> None:
    for _ in range(round(seconds / STEP)):
        robot.step(STEP)


def gait(robot: SimRobot, name: str) -> None:
    g = GAITS[name]
    robot.set_gait(int(g.kind), g.period, g.duty, g.sweep, g.down, g.phases, g.direction)


def walk(robot: SimRobot, seconds: float) -> None:
    """Walk with the tether paid out, then stand and rest."""
    robot.set_winch(-0.04)
    gait(robot, 'walk')
    run(robot, seconds)
    robot.set_winch(0.0)
    gait(robot, 'stand')
    run(robot, 1.0)


def take_up(robot: SimRobot) -> None:
    """The rope just taut (1 N), as behavior_node's take-up leaves it."""
    w = robot.winch
    dist, _ = w.geometry(robot.x_p, robot.h)
    w.rope_length = w.spool_position + dist - 1.0 / w.rope_k


def burrow(robot: SimRobot, retract, final) -> tuple[float, float]:
    """Stream the gait from the legs' pose, the rope taken up at standing; (h, theta_b) of p
    at the end, m and rad."""
    a = robot.leg_angles()
    start = (0.5 * (a[0] + a[1]), 0.5 * (a[2] + a[3]))
    t, taut = 0.0, False
    while t < gait_duration(start, retract, final, SPEED) + 1.5:
        q = gait_targets(t, start, retract, final, SPEED)
        if not taut and robot._physical and max(abs(q[0]), abs(q[1])) < D(1.0):
            take_up(robot)
            taut = True
        robot.set_legs([q[0], q[0], q[1], q[1]])
        run(robot, STREAM)
        t += STREAM
    assert robot.physics is not None and not robot.physics.failed
    _, z, theta_b = robot.physics.pose
    return z, theta_b


def walked_robot() -> SimRobot:
    robot = SimRobot(physics=PhysicsBody(), physics_walk=False,
                     winch=WinchSled(sled_mass=0.6, rope_length=1.0))
    walk(robot, 2.5)
    return robot


def test_a_reburrow_in_place_ends_elsewhere_and_one_after_a_walk_where_a_fresh_one_does():
    fresh = burrow(walked_robot(), *AGAIN)
    in_place = walked_robot()
    burrow(in_place, *FIRST)
    again_in_place = burrow(in_place, *AGAIN)
    stepped_off = walked_robot()
    burrow(stepped_off, *FIRST)
    walk(stepped_off, 1.0)
    again_stepped_off = burrow(stepped_off, *AGAIN)
    # Measured (2026-11-28): fresh 31.3 mm, 16.5 deg; in place 27.5 mm, 22.1 deg; after the
    # walk 31.4 mm, 16.6 deg. The plan's band for this gait is about 1 deg of pitch (two of
    # its one-sigma spreads, docs/design/burrow-planner.md), and the IMU check allows 1 deg
    # more: a 3 deg miss is a burrow the plan does not describe.
    assert abs(again_in_place[1] - fresh[1]) > D(3.0), (again_in_place, fresh)
    # The walk puts the body down level where it stopped, as the fresh start does: the same
    # burrow up to where the stream's 20 ms targets fall against the physics' 10 ms steps
    # (the two starts differ in x and in time; RFT on level sand is the same everywhere). One
    # step of lead or lag is 0.6 deg of leg at 1 rad/s; measured 0.1 deg of pitch, 0.1 mm.
    assert again_stepped_off[1] == pytest.approx(fresh[1], abs=D(0.5))
    assert again_stepped_off[0] == pytest.approx(fresh[0], abs=1e-3)
