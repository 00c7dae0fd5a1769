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


def walked_burrow_physics_robot(seconds: float = 2.5) -> SimRobot:
    """``--body burrow-physics`` after `seconds` of the driver's scripted walk: the legs are
    left somewhere in their swing and the physics rests."""
    from minirquad_driver.gaits import GAITS
    robot = SimRobot(physics=PhysicsBody(), physics_walk=False)
    g = GAITS['walk']
    robot.set_gait(int(g.kind), g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
    for _ in range(round(seconds / STEP)):
        robot.step(STEP)
    return robot


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


def test_burrow_physics_walks_scripted_and_burrows_with_the_physics_where_the_walk_ended():
    """``--body burrow-physics``: the physics rests while the robot walks (the scripted walk:
    upright, at walk_speed), then is put down where the walk left p and burrows; the burrowed
    pose is the physics' own. A walk after it starts from the legs the physics left."""
    from minirquad_driver.gaits import GAITS
    from minirquad_sim.winch import WinchSled
    # a slack rope (1 m paid out), so the walk goes where the script sends it
    robot = SimRobot(physics=PhysicsBody(), physics_walk=False, winch=WinchSled(rope_length=1.0))
    body = robot.physics
    assert body is not None
    g = GAITS['walk']
    robot.set_gait(int(g.kind), g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
    t_physics, x0 = body.sim.t, robot.x_p
    for _ in range(round(1.5 / STEP)):
        robot.step(STEP)
    # the physics did not step while walking; the script moved p forward at walk_speed and
    # raised the body toward h_walk, upright (it relaxes from the physics' pitch)
    assert body.sim.t == t_physics
    walked_to = x0 + robot.geometry.walk_speed * 1.5
    assert robot.x_p == pytest.approx(walked_to, abs=1e-9)
    assert abs(robot.theta_b) < math.radians(0.1)
    # standing up is scripted too; the physics takes the robot once the legs stand
    st = GAITS['stand']
    robot.set_gait(int(st.kind), st.period, st.duty, st.sweep, st.down, st.phases, st.direction)
    while body.sim.t == t_physics:
        robot.step(STEP)
        assert robot.time < 5.0, 'never put down'
    assert all(a == pytest.approx(st.down, abs=1e-3) for a in robot.leg_angles())
    # put down where the walk ended: p within a few mm of it after settling, legs as they were
    assert body.pose[0] == pytest.approx(walked_to, abs=5e-3)
    # the rope taken up to ~1 N, as at power-up (an untethered SH burrow overturns the robot:
    # docs/design/walk-burrow-physics.md)
    dist, _ = robot.winch.geometry(robot.x_p, robot.h)
    robot.winch.rope_length = dist - 1.0 / robot.winch.rope_k
    robot.burrow(BurrowMode.SH)
    for _ in range(round(5.0 / STEP)):
        robot.step(STEP)
    assert not body.failed and robot.mode is Mode.ANCHORED
    assert (robot.x_p, robot.h, robot.theta_b) == body.pose
    assert robot.h < robot.geometry.h_walk - 0.01
    # walking again: the script takes the body, its servos starting from the physics' legs
    burrowed = robot.leg_angles()
    robot.set_gait(int(g.kind), g.period, g.duty, g.sweep, g.down, g.phases, g.direction)
    for a, b in zip(robot.leg_angles(), burrowed):
        assert a == pytest.approx(b, abs=1e-9)
    t_physics = body.sim.t
    robot.step(STEP)
    assert body.sim.t == t_physics


def test_a_leg_command_after_the_walk_stands_the_robot_up_before_the_physics_takes_it():
    """The behaviour node's burrow is a stream of leg commands, sent right after the walk.
    The scripted walk leaves the legs anywhere in their swing (here one pair behind, one far
    forward); put down on those the robot cannot stand and the physics stops (no_rest, its
    legs then frozen for the rest of the run). The script stands the robot up first, the
    physics takes it, and the command runs on the physics."""
    robot = walked_burrow_physics_robot()
    body = robot.physics
    assert body is not None
    swing = robot.leg_angles()
    assert max(abs(a) for a in swing) > math.radians(90.0)     # mid-swing, not standing
    t_physics = body.sim.t
    final = (math.radians(-40.0), math.radians(-20.0))
    robot.set_legs([final[0], final[0], final[1], final[1]])
    assert body.sim.t == t_physics and robot.mode is Mode.IDLE   # standing up first
    for _ in range(round(4.0 / STEP)):
        robot.step(STEP)
    assert not body.failed
    assert body.sim.t > t_physics
    for i, a in enumerate(robot.leg_angles()):
        assert a == pytest.approx(final[0 if i < 2 else 1], abs=math.radians(1.0))
    assert (robot.x_p, robot.h, robot.theta_b) == body.pose
    # an e-stop while standing up cancels the deferred command: the legs hold, nothing runs
    robot2 = walked_burrow_physics_robot()
    assert robot2.physics is not None
    t_physics = robot2.physics.sim.t
    robot2.burrow(BurrowMode.SH)
    robot2.set_estop(True)
    held = robot2.leg_angles()
    for _ in range(round(1.0 / STEP)):
        robot2.step(STEP)
    assert robot2.leg_angles() == held and robot2.mode is Mode.IDLE
    assert robot2.physics.sim.t == t_physics and not robot2.physics.failed


def test_the_stand_up_follows_a_stream_of_leg_commands_down_to_standing():
    """behavior_node's planned burrow streams leg targets every 20 ms: a ramp at the burrow
    speed (1 rad/s) from where the walk left the legs down to standing, held there until the
    legs are there, then on to the retracting pose. The script's stand-up (8 rad/s) follows
    that stream instead of overtaking it, so once the physics has the body, at standing, the
    legs only go on toward the retracting pose. Overtaken, the physics took the body at
    standing and the next command, still on its way down, swung the legs forward through the
    sand again: a stroke no plan simulated."""
    from rftgls_conventions import wrap_angle
    robot = walked_burrow_physics_robot()
    start = [wrap_angle(a) for a in robot.leg_angles()]
    assert max(abs(a) for a in start) > math.radians(20.0)     # not standing
    retract = [math.radians(-40.0)] * 2 + [math.radians(-20.0)] * 2     # PL, PR, DL, DR
    speed, period = 1.0, 0.02
    t, t_stroke, after = 0.0, None, []
    while t < 6.0:
        if t_stroke is None:
            targets = [math.copysign(max(abs(a) - speed * t, 0.0), a) for a in start]
            if all(x == 0.0 for x in targets) and all(
                    abs(a) < math.radians(0.5) for a in robot.leg_angles()):
                t_stroke = t
        if t_stroke is not None:
            targets = [max(r, -speed * (t - t_stroke)) for r in retract]
        robot.set_legs(targets)
        for _ in range(round(period / STEP)):
            robot.step(STEP)
            if robot.physics is not None and robot._physical:
                after.append(robot.leg_angles())
        t += period
    assert t_stroke is not None and after and not robot.physics.failed
    # from the moment the physics has the body: never forward of standing, then the stroke
    assert max(max(a) for a in after) < math.radians(0.5), max(max(a) for a in after)
    for a, r in zip(after[-1], retract):
        assert a == pytest.approx(r, abs=math.radians(2.0))


@pytest.mark.parametrize('body', ['physics', 'burrow-physics'])
def test_the_command_line_builds_each_physics_body_and_refuses_it_on_the_firmware(body, capsys):
    from minirquad_sim.main import _make_mcu, _physics, parse_args, run
    from minirquad_sim.mcu import McuConfig
    args = parse_args(['--body', body])
    mcu = _make_mcu(args, None, McuConfig(), 0.0, lambda *_: None)
    robot = mcu.robot
    assert robot.physics is not None and _physics(args) is not None
    assert robot.physics_walk == (body == 'physics')
    # the compiled firmware drives servos the physics body cannot follow: exit 2, one line
    assert run(parse_args(['--body', body, '--mcu', 'firmware'])) == 2
    err = capsys.readouterr().err.strip()
    assert err.count('\n') == 0 and f'--body {body} runs with the Python MCU' in err
