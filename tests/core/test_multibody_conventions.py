"""The multibody simulation's sign conventions against the RFT core and the geometry, the
walking gait's footfall order and the MCU loop's angle error
(docs/design/walk-burrow-physics.md, "Checks")."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.multibody.contact import Contact
from rftgls_core.multibody.gaits import WalkGait
from rftgls_core.multibody.robot import BasePose, from_preset
from rftgls_core.multibody.simulate import position_error
from rftgls_core.rft.engine import BuriedBody
from rftgls_core.rft.media import get_medium
from rftgls_core.rft.models import make_model
from rftgls_core.robots.presets import minirquad

MODEL = make_model('agarwal', get_medium('m90_sand'))
# Finite-difference step of the joint angle, rad. The fitted twist's truncation error is
# about step x |r| x |qdot| / 2 <= 1e-6 x 0.2 m / 2 = 1e-7 m/s and its round-off about
# eps x 0.2 m / step = 4e-11 m/s, so 1e-6 (m/s, rad/s) bounds the difference to the Jacobian.
FD_STEP = 1e-6
FD_TOL = 1e-6


def fitted_twist(before: np.ndarray, after: np.ndarray, ref: np.ndarray, dt: float):
    """The planar twist (vx, vz, wy) at ref that moves the points `before` to `after` in dt,
    least squares over v = (vx + wy r_z, vz - wy r_x): the rigid motion the geometry made."""
    v = (after - before) / dt
    r = before - ref
    a = np.zeros((2 * len(r), 3))
    a[0::2, 0], a[0::2, 2] = 1.0, r[:, 2]
    a[1::2, 1], a[1::2, 2] = 1.0, -r[:, 0]
    b = np.empty(2 * len(r))
    b[0::2], b[1::2] = v[:, 0], v[:, 2]
    return np.linalg.lstsq(a, b, rcond=None)[0]


@pytest.mark.parametrize('pull', ['backward', 'forward'])
@pytest.mark.parametrize('q_deg', [-60.0, 0.0, 35.0])
def test_a_legs_joint_twist_is_how_its_facets_move(pull, q_deg):
    """The twist a turning leg's facets get in the wrench (rate x J) is the motion the posed
    geometry makes when the joint turns, and the part's wrench is the RFT core's for it."""
    robot = from_preset(minirquad(), pull)
    base = BasePose(0.01, 0.02, math.radians(4.0))
    q = np.full(4, math.radians(q_deg))
    posed = robot.pose(base, q)
    nudged = robot.pose(base, q + np.array([FD_STEP, 0.0, 0.0, 0.0]))
    tw = fitted_twist(posed.legs[0].centroids, nudged.legs[0].centroids, posed.ref, FD_STEP)
    assert np.abs(tw - posed.jac[0]).max() <= FD_TOL
    contact = Contact(posed, MODEL, np.array([1.0, 0.0, 0.0, 0.0]))
    k = next(i for i, pt in enumerate(contact.parts) if pt.legs == (0,))
    got = contact.part_wrenches(np.zeros((1, 3)))[0, k]
    ref = BuriedBody(posed.legs[0], MODEL, ref=posed.ref, backend='numpy').planar_wrench(
        posed.jac[0])
    assert np.abs(got - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())


def test_sand_resists_a_turning_leg_and_the_servo_works_against_it():
    """A buried leg swung toe-forward (+x_B) is pushed back (Fx < 0) and, pressed down, up
    (Fz > 0); its servo's torque points along its rate (positive work into the sand)."""
    robot = from_preset(minirquad())
    posed = robot.pose(BasePose(0.0, 0.03, 0.0), np.radians([-30.0, -30.0, -30.0, -30.0]))
    for rate in (1.0, -1.0):
        contact = Contact(posed, MODEL, np.array([rate, 0.0, rate, 0.0]))
        k = next(i for i, pt in enumerate(contact.parts) if 0 in pt.legs)
        w = contact.part_wrenches(np.zeros((1, 3)))[0, k]
        # toe behind the hip: turning toe-forward moves it forward and down, back: back and up
        if rate > 0:
            assert w[0] < 0.0 and w[1] > 0.0
        else:
            assert w[0] > 0.0
        assert contact.parts[k].torque(w) * rate > 0.0


def test_a_positive_pitch_rate_about_y_tips_the_front_down():
    """BasePose.moved: a twist wy > 0 (about +y) lowers the +x_B end and decreases theta_b,
    as the velocity field v = w x r says (theta_b > 0 lifts the front)."""
    pose = BasePose(0.0, 0.05, math.radians(3.0))
    front = np.array([0.15, 0.0, 0.0])
    ref = pose.origin
    dt = 1e-6
    moved = pose.moved(np.array([0.0, 0.0, 1.0]), ref, dt)
    before = pose.origin + pose.rotation @ front
    after = moved.origin + moved.rotation @ front
    r = before - ref
    assert moved.theta_b < pose.theta_b
    assert np.allclose((after - before) / dt, [r[2], 0.0, -r[0]], atol=1e-6)


def test_the_amble_steps_in_the_lateral_sequence():
    """Footfalls (a leg entering its stance arc) in the cyclic order LH, LF, RH, RF, a
    quarter cycle apart."""
    robot = from_preset(minirquad())
    gait = WalkGait(robot, duration=4.0)
    ts = np.arange(0.0, 2.0 * gait.period, 1e-3)
    stance = np.array([gait.stance(t) for t in ts])
    falls = []
    for name, i in robot.leg_order.items():
        on = np.flatnonzero(stance[1:, i] & ~stance[:-1, i]) + 1
        falls += [(ts[k], name) for k in on]
    falls.sort()
    names = [n for _, n in falls]
    first = names.index('LH')
    assert (names[first:] + names[:first])[:4] == ['LH', 'LF', 'RH', 'RF']
    assert np.allclose(np.diff([t for t, _ in falls]), 0.25 * gait.period, atol=2e-3)


def test_the_loop_takes_the_short_way_round_for_legs_that_turn_fully():
    """MiniRHex's pd_controller: a full-turn leg 200 deg behind its reference is sent back
    160 deg; the plain difference stays for a leg with joint limits."""
    robot = from_preset(minirquad())
    q = np.zeros(4)
    ref = np.full(4, math.radians(200.0))
    err = position_error(robot, ref, q)
    assert np.allclose(err, math.radians(-160.0))
    limited = robot.__class__(**{**robot.__dict__, 'legs': tuple(
        leg.__class__(**{**leg.__dict__, 'limits': (-4.0, 4.0)}) for leg in robot.legs)})
    assert np.allclose(position_error(limited, ref, q), math.radians(200.0))


def test_a_servo_over_its_line_runs_where_torque_and_line_meet():
    """A buried leg commanded at the no-load speed (where the line gives no torque) runs at the
    largest rate its servo's line allows: its torque there is within the line, and 5 % more
    rate (the search stops within balance.FRACTION_TOL = 2 %) is beyond it."""
    from rftgls_core.multibody import balance as bal_mod
    from rftgls_core.multibody.servo import XL330_M077_5V as servo
    robot = from_preset(minirquad())
    posed = robot.pose(BasePose(0.0, 0.03, 0.0), np.radians([-30.0, -30.0, -30.0, -30.0]))
    command = np.array([servo.no_load_speed, 0.0, servo.no_load_speed, 0.0])
    b = bal_mod.balance(posed, MODEL, servo, command, posed.gravity, np.zeros(3), 0.01, 1e-5)
    i = 0
    rate = b.rates[i]
    assert 0.0 < rate < command[i] and not b.stalled[i]
    assert abs(b.torques[i]) <= servo.torque_limit(rate) * (1.0 + 1e-9)
    faster = min(command[i], rate + 0.05 * command[i])
    rates = np.where(command != 0.0, faster, 0.0)
    b2 = bal_mod.step_balance(posed, MODEL, rates, posed.gravity, np.zeros(3), 0.01, 1e-5)
    assert abs(b2.torques[i]) > servo.torque_limit(faster)


def test_a_walk_starts_from_standing_level():
    """MiniRHex stands (every leg at 0) before it walks: the robot is put down level, not in
    its clocks' first pose (one leg up, two under it: 27 deg nose down)."""
    from rftgls_core.multibody.simulate import Simulator
    robot = from_preset(minirquad())
    gait = WalkGait(robot, duration=1.0)
    assert np.array_equal(gait.start(), np.zeros(4))
    sim = Simulator(robot, get_medium('m90_sand'))
    sim.place(gait.start())
    assert abs(math.degrees(sim.pose.theta_b)) < 2.0
