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


def flattening_torque(rate: float) -> float:
    """A stand-in for the sand's torque on a walking leg (N m against |rate| rad/s, toward the
    command's sign), of the shape measured in the walk at 1.1 s: 0.076, 0.165, 0.21, 0.22 N m
    at 5, 20, 50, 100 % of a 5.9 rad/s command."""
    return -0.221 * (1.0 - math.exp(-abs(rate) / 0.8))


COMMAND = np.array([0.0, 0.0, -5.919, 0.0])     # rad/s: one leg driven, as at 1.1 s


@pytest.fixture
def stand_in(monkeypatch):
    """balance.step_balance replaced by the stand-in torque; returns the list of its calls
    (rates, restarts). converged[0] False: no balance is found without restarts."""
    from rftgls_core.multibody import balance as bal_mod
    calls: list = []
    converged = [True]

    def fake_step(posed, model, rates, load, xi_prev, dt, creep, backend='auto', packs=None,
                  restarts=bal_mod.RESTARTS):
        calls.append((rates.copy(), restarts))
        n = len(rates)
        b = bal_mod.Balance('move', np.zeros(3), np.asarray(rates, float).copy(), np.zeros(n),
                            np.zeros(n, bool), np.zeros(n, bool),
                            converged=converged[0] or restarts > 0)
        b.torques = np.array([flattening_torque(r) if r else 0.0 for r in rates])
        return b

    monkeypatch.setattr(bal_mod, 'step_balance', fake_step)
    return calls, converged


def meeting_rate(servo) -> float:
    """|rate| (rad/s) where the stand-in torque meets the servo's line."""
    from scipy.optimize import brentq
    return brentq(lambda r: -flattening_torque(r) - servo.torque_limit(r), 1e-6,
                  abs(COMMAND[2]))


def search(prior=None):
    from rftgls_core.multibody import balance as bal_mod
    from rftgls_core.multibody.servo import XL330_M077_5V as servo
    return bal_mod.balance(None, None, servo, COMMAND, np.zeros(3), np.zeros(3), 1e-3, 1e-5,
                           prior=prior)


def test_the_servo_line_search_converges_on_a_flattening_torque(stand_in):
    """The sand's torque on a leg rises steeply at small rates and flattens at large ones
    (concave). Plain regula falsi then keeps its low end for good and creeps down from above:
    with its 6 searches it stopped a walking leg at 5 % of its command where the line allowed
    30-50 % (check 15). The search must end within balance.FRACTION_TOL of where torque and line
    meet (flattening_torque)."""
    from rftgls_core.multibody import balance as bal_mod
    from rftgls_core.multibody.servo import XL330_M077_5V as servo
    rate = abs(search().rates[2])
    assert abs(flattening_torque(rate)) <= servo.torque_limit(rate) * (1.0 + 1e-9)
    assert meeting_rate(servo) - rate <= bal_mod.FRACTION_TOL * abs(COMMAND[2])


@pytest.mark.parametrize('near', [0.999, 1.01, 0.9, 1.3, 0.3])
def test_the_servo_line_search_from_the_last_rate_meets_the_same_tolerance(stand_in, near):
    """balance's prior: a leg the line refuses tries the rate the last step settled on
    (here `near` x where torque and line meet) and then one tolerance beside it. Close priors
    (0.1 %, 1 % off) close the bracket in three solves (full command, prior, beside) where the
    search without one takes more; far ones (10 %, 30 %, 70 % off) hand their bracket to
    the search. Either way the answer is within the line and within FRACTION_TOL of the
    meeting rate, as without a prior."""
    from rftgls_core.multibody import balance as bal_mod
    from rftgls_core.multibody.servo import XL330_M077_5V as servo
    calls, _ = stand_in
    meet = meeting_rate(servo)
    search()
    without = len(calls)
    calls.clear()
    rate = abs(search(prior=np.array([0.0, 0.0, -near * meet, 0.0])).rates[2])
    assert abs(flattening_torque(rate)) <= servo.torque_limit(rate) * (1.0 + 1e-9)
    assert meet - rate <= bal_mod.FRACTION_TOL * abs(COMMAND[2])
    if abs(near - 1.0) < bal_mod.BESIDE:
        assert len(calls) == 3 < without, (len(calls), without)


def test_the_servo_line_search_probes_without_restarts_and_answers_with_them(stand_in):
    """The search's probes skip step_balance's random restarts; the answer it keeps never
    does: a probe that found no balance is solved again with them when it is the answer.
    Stand-in: no balance without restarts anywhere, the same torque with them."""
    from rftgls_core.multibody import balance as bal_mod
    calls, converged = stand_in
    converged[0] = False
    b = search()
    assert b.converged
    assert calls[0][1] == bal_mod.RESTARTS and calls[-1][1] == bal_mod.RESTARTS
    assert np.array_equal(calls[-1][0], b.rates)
    assert all(r == 0 for _, r in calls[1:-1]) and len(calls) > 3


def test_a_walking_leg_in_the_sand_runs_where_its_line_allows():
    """The walk's right hind leg at 1.1 s (pose, joints, last twist and step of the run before
    the search was fixed): it lies ahead of its hip in the sand, 96 deg behind its clock. It
    ran at 0.30 rad/s with 0.076 N m where its servo's line allows ~2 rad/s; now its torque
    is within the line and 5 % of its command more is beyond it."""
    from rftgls_core.multibody import balance as bal_mod
    from rftgls_core.multibody.servo import XL330_M077_5V as servo
    robot = from_preset(minirquad())
    pose = BasePose(0.08638445531030853, 0.02779042855923999, -0.10962621735628601)
    q = np.array([-1.9499540608488335, -0.5886742921400382, -4.67043014533647,
                  -4.342193311338698])
    xi_prev = np.array([-0.0696703528392742, -0.13236184107752075, -1.9504105626699821])
    command = np.array([-4.815, -0.561, -5.919, -4.86])      # rad/s, the MCU's at 1.1 s
    posed = robot.pose(pose, q)
    b = bal_mod.balance(posed, MODEL, servo, command, posed.gravity, xi_prev, 0.00177, 1e-5)
    i = 2
    rate = b.rates[i]
    assert not b.stalled[i]
    assert abs(b.torques[i]) <= servo.torque_limit(rate) * (1.0 + 1e-9)
    rates = b.rates.copy()
    rates[i] = rate + 0.05 * command[i]
    b2 = bal_mod.step_balance(posed, MODEL, rates, posed.gravity, xi_prev, 0.00177, 1e-5)
    assert abs(b2.torques[i]) > servo.torque_limit(rates[i])
    # Started from the rates of a step before (this answer 1 % slower), the search ends at a
    # rate within the line again, within FRACTION_TOL of the answer without a prior (each
    # answer is within the tolerance of where torque and line meet, on its low side).
    b3 = bal_mod.balance(posed, MODEL, servo, command, posed.gravity, xi_prev, 0.00177, 1e-5,
                         prior=0.99 * b.rates)
    assert abs(b3.torques[i]) <= servo.torque_limit(b3.rates[i]) * (1.0 + 1e-9)
    assert abs(b3.rates[i] - rate) <= bal_mod.FRACTION_TOL * abs(command[i])
