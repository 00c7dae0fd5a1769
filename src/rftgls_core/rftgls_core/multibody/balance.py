"""One quasi-static instant: the leg rates the servos manage and the base twist that balances.

Given the posed robot, each leg's commanded rate, gravity and the tether, find

    sum_parts W_part(xi, qdot) + W_gravity + W_tether = 0            (3 equations, xi unknown)

on the set-valued closure of RFT (roots.py), after the resting check (support.py): if the
resting parts (base, legs that do not turn) can supply what the turning legs and the loads
need, the base stands still (xi = 0). Each servo then gives the torque its leg needs,
tau = -J . W_leg (contact.Part.torque); where that exceeds its torque-speed line
(servo.ServoSpec.torque_limit) the leg slows to the speed the line allows at that torque, and
stalls when none is left. A stalled leg rests, held by its gear, while its commanded angle
runs ahead (the velocity loop is saturated: the servo draws its stall current).

Resting parts carry a statically indeterminate share. The model (`hold_model`):
'frozen' (default): a part that stops keeps the wrench it carried while moving (granular
stresses stay locked in; the paper takes static and kinetic resistance as equal) and any
change of the load is shared at the onset of slip (support.shares); 'proportional': the whole
load is shared at the onset of slip, with no memory. A single resting part carries it all.

When no leg turns (a hold, or every turning leg stalled) the robot rests if the resting parts
hold the load, and otherwise slips (simulate.py integrates the slip).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..rft.base import StressModel
from ..surfaces.scaling import Scaling
from . import support
from .contact import Contact, Part
from .robot import PosedMultibody
from .roots import closure_root
from .servo import ServoSpec

HOLD_MODELS = ('frozen', 'proportional')
# |F| at which the root of the ramped map counts as found (roots.py), scaled units (forces by
# the weight, the moment by weight x L_c).
NEWTON_TOL = 1e-11
# Equilibrium tolerance every step is held to: |residual| <= RESIDUAL_TOL x weight.
RESIDUAL_TOL = 1e-8
STALL_ITERATIONS = 4
MIN_FRACTION = 1e-3    # a leg slowed below this fraction of its command stalls


@dataclass
class Balance:
    """The outcome of one instant.

    mode: 'move' (the base moves with xi), 'rest' (xi = 0, resting parts hold), 'hold'
    (nothing turns; simulate.py decides rest or slip), 'no_contact', 'no_root'.
    xi: base twist (vx, vz, wy) at p, m/s and rad/s. rates: each leg's rate, rad/s.
    torques: each servo's torque about its axis, N m (stall torque for a stalled leg).
    stalled, slowed: per leg. residual: |sum of wrenches| on the closure, N (scaled by the
    weight: forces in N, the moment divided by L_c). bridge: the jump the root sits on (same
    units; ~0 on a smooth root). leg_wrench: each leg's sand wrench (one leg), base_wrench.
    """

    mode: str
    xi: np.ndarray
    rates: np.ndarray
    torques: np.ndarray
    stalled: np.ndarray
    slowed: np.ndarray
    residual: float = 0.0
    bridge: float = 0.0
    leg_wrench: dict = field(default_factory=dict)
    base_wrench: np.ndarray = field(default_factory=lambda: np.zeros(3))
    detail: str = ''
    contact: Contact | None = None


def scaling_of(posed: PosedMultibody) -> Scaling:
    """The scaled metric of the stack (anchor.AnchorModel): s_F = the weight, L_c."""
    return Scaling(posed.robot.weight, posed.robot.char_length)


def tether_wrench(tension: float, phi: float) -> np.ndarray:
    """Planar wrench of the tether at p: tension (N) along d(phi) = (-cos phi, sin phi)."""
    return tension * np.array([-math.cos(phi), math.sin(phi), 0.0])


def resting_shares(contact: Contact, resting: list[Part], w_need: np.ndarray,
                   frozen: dict, scaling: Scaling, hold_model: str) -> list[np.ndarray]:
    """The wrench each resting part carries when together they supply w_need (see module)."""
    if len(resting) == 1:
        return [np.asarray(w_need, dtype=float).copy()]
    if hold_model == 'frozen':
        kept = [_frozen(pt, frozen) for pt in resting]
        delta = w_need - np.sum(kept, axis=0)
        if np.linalg.norm(scaling.wrench_to_scaled(delta)) <= RESIDUAL_TOL:
            return kept
        extra = support.shares(resting, delta, scaling)
        if extra is not None:
            return [k + e for k, e in zip(kept, extra)]
    shares = support.shares(resting, w_need, scaling)
    if shares is None:
        # The load cannot be held by these parts (the caller checked it can): equal shares.
        return [w_need / len(resting) for _ in resting]
    return shares


def _frozen(pt: Part, frozen: dict) -> np.ndarray:
    if pt.jac is None:
        return np.asarray(frozen.get('base', np.zeros(3)), dtype=float)
    return sum((np.asarray(frozen.get(i, np.zeros(3)), dtype=float) for i in pt.legs),
               start=np.zeros(3))


def _record(bal: Balance, contact: Contact, parts: list[Part], wrenches: list[np.ndarray]):
    """Store each part's wrench per leg (and the base's) and the servo torques."""
    for pt, w in zip(parts, wrenches):
        if pt.jac is None:
            bal.base_wrench = np.asarray(w, dtype=float)
            continue
        tau = pt.torque(w)
        for i in pt.legs:
            bal.leg_wrench[i] = np.asarray(w, dtype=float) / pt.count
            bal.torques[i] = tau


def equilibrium(posed: PosedMultibody, model: StressModel, rates: np.ndarray, load: np.ndarray,
                frozen: dict, xi_guess: np.ndarray, hold_model: str = 'frozen',
                backend: str = 'auto') -> Balance:
    """Balance at fixed leg rates (rad/s): rest, move (xi from the closure root), or 'hold'
    when no buried leg turns. load: gravity plus tether (N, N, N m about p)."""
    n = len(posed.legs)
    bal = Balance('hold', np.zeros(3), np.asarray(rates, dtype=float).copy(), np.zeros(n),
                  np.zeros(n, bool), np.zeros(n, bool))
    contact = Contact(posed, model, rates, backend=backend)
    bal.contact = contact
    if not contact.any:
        bal.mode = 'no_contact'
        bal.detail = 'no part of the robot is below the free surface'
        return bal
    moving, resting = contact.moving(), contact.resting()
    if not moving:
        return bal
    scaling = scaling_of(posed)
    w_turn = contact.moving_at_rest()
    w_need = -(w_turn + load)
    if resting and support.rests(resting, w_need, scaling):
        bal.mode = 'rest'
        shares = resting_shares(contact, resting, w_need, frozen, scaling, hold_model)
        _record(bal, contact, resting, shares)
        _record(bal, contact, moving, [pt.wrenches(np.zeros((1, 3)))[0] for pt in moving])
        return bal
    robot = posed.robot
    v_ref = max(abs(pt.rate) for pt in moving) * robot.char_length
    tscale = np.array([v_ref, v_ref, v_ref / robot.char_length])
    fscale = scaling.diag

    def f(x: np.ndarray, eps: float = 0.0) -> np.ndarray:
        # each part's wrench rides along: the shares at the closure point (roots.Root.extra)
        xi = x * tscale
        per = [pt.smooth_wrenches(xi, eps) if eps else pt.wrenches(xi) for pt in contact.parts]
        return np.column_stack([(np.sum(per, axis=0) + load) / fscale] + per)

    x0 = np.asarray(xi_guess, dtype=float) / tscale
    if not np.any(x0) and resting:
        # Start off the resting parts' jump at zero, along the twist they would slip with.
        res = support.fit(resting, np.zeros(3), scaling, direction=-w_need).capacity(0.0)
        if res.slip_twist is not None:
            t = np.asarray(res.slip_twist) / tscale
            x0 = 1e-3 * t / np.linalg.norm(t)
    root = closure_root(f, x0, NEWTON_TOL)
    if not root.converged:
        bal.mode = 'no_root'
        bal.detail = (f'no balance of the turning legs found (|F| {root.pointwise:.3g} x '
                      f'weight after {root.evaluations} evaluations)')
        return bal
    bal.mode = 'move'
    bal.xi = root.x * tscale
    bal.residual = root.residual * robot.weight
    bal.bridge = root.bridge * robot.weight
    _record(bal, contact, contact.parts, list(root.extra.reshape(-1, 3)))
    return bal


def balance(posed: PosedMultibody, model: StressModel, servo: ServoSpec, command: np.ndarray,
            load: np.ndarray, frozen: dict, xi_guess: np.ndarray, hold_model: str = 'frozen',
            backend: str = 'auto') -> Balance:
    """Balance with torque-limited servos: legs whose torque exceeds the servo's line slow to
    the speed the line allows, or stall (module doc). command: rate per leg, rad/s."""
    if hold_model not in HOLD_MODELS:
        raise ValueError(f'hold_model must be one of {", ".join(HOLD_MODELS)}, got '
                         f'{hold_model!r}')
    command = np.asarray(command, dtype=float)
    frac = np.where(command != 0.0, 1.0, 0.0)
    bal = None
    for it in range(STALL_ITERATIONS):
        bal = equilibrium(posed, model, frac * command, load, frozen, xi_guess, hold_model,
                          backend)
        if bal.mode not in ('move', 'rest') or it == STALL_ITERATIONS - 1:
            break
        new = frac.copy()
        for i, c in enumerate(command):
            if frac[i] == 0.0:
                continue
            tau = bal.torques[i]
            if tau * c > 0.0 and abs(tau) > servo.torque_limit(frac[i] * c) * (1.0 + 1e-9):
                slow = servo.speed_at(tau) / abs(c)
                new[i] = min(frac[i], slow)
                if new[i] < MIN_FRACTION:
                    new[i] = 0.0
        if np.array_equal(new, frac):
            break
        frac = new
        if bal.mode == 'move':
            xi_guess = bal.xi
    assert bal is not None
    bal.stalled = (command != 0.0) & (frac == 0.0)
    bal.slowed = (frac > 0.0) & (frac < 1.0)
    for i in np.flatnonzero(bal.stalled):
        bal.torques[i] = math.copysign(servo.stall_torque, command[i])
    return bal
