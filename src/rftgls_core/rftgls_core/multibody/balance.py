"""One step: the leg rates the servos manage and the base twist that balances.

Given the posed robot, each leg's commanded rate, gravity and the tether, the base twist xi
(vx, vz, wy at p) of the step solves

    sum_parts W_part(xi, qdot) + W_gravity + W_tether = M (xi - xi_prev) / dt         (1)

on RFT's closure: each part's wrench W(xi + qdot J) is RFT with its two jumps resolved the way
the closure allows (evaluate.py): a facet at its leading/trailing switch carries a fraction of
its stress (a ramp of width 1e-3 in n . v_hat), and a facet at rest any fraction (a ramp of
width `creep` in speed). M is the base's mass matrix at p.

Why the right side: the quasi-static balance (M = 0) has no finite root where the robot sits
on the edge of its support and the legs' turn weakens it, as it does after every sinking: the
base would have to move infinitely faster than the legs, i.e. fall. With M the fall is
integrated (backward Euler, unconditionally stable) until the sand holds the robot again;
wherever the robot moves steadily or rests the term vanishes and (1) is the quasi-static
balance. Each step reports the inertial wrench M (xi - xi_prev) / dt so a reader sees where
the motion was not quasi-static. The creep ramp makes resting parts carry their share as at
the onset of slip under the load (they creep along the twist that would make them slip,
at speeds below `creep`), one member of the set-valued closure at rest.

Each servo gives the torque its leg needs, tau = -J . W_leg (contact.Part.torque); where that
exceeds its torque-speed line (servo.ServoSpec.torque_limit) the leg slows to the speed the
line allows at that torque, and stalls when none is left: it rests, held by its gear, while its
commanded angle runs ahead (the velocity loop saturated: the servo draws its stall current).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from ..rft.base import StressModel
from ..surfaces.scaling import Scaling
from .affine_root import affine_root
from .contact import Contact, Part
from .robot import PosedMultibody
from .servo import ServoSpec

# |residual of (1)| / weight that Newton aims at and at which a step is accepted.
NEWTON_TOL = 1e-10
RESIDUAL_TOL = 1e-8
# Ramp schedules (roots.py) tried in turn from the last twist, from rest, from a free fall and
# then from restarts around the last twist (a flat face of the base switches all its facets
# at once: a jump the size of the face's force, with local minima of |residual| beside it).
# The last width of a schedule is the closure the balance is certified on: a facet within
# that distance of its leading/trailing switch in n . v_hat (1e-4: 0.006 deg; 1e-3: 0.06 deg;
# 1e-2: 0.6 deg; the C-leg's neighbouring facets differ by 7.5 deg) carries a fraction of its
# stress. A facet sitting right on a switch makes one width's |residual| a local minimum that
# another width does not have, hence several widths from the last twist.
EPS = ((1e-3,), (3e-2, 1e-3), (1e-2,), (1e-4,))
RESTARTS = 8
STALL_ITERATIONS = 16  # servo-line searches per step at most (balance; Illinois needs ~6-12)
MIN_FRACTION = 1e-3    # a leg slowed below this fraction of its command stalls
FRACTION_TOL = 0.02    # the servo-line search stops within 2 % of a leg's rate (balance)
# a probe one tolerance beside a prior that closes the bracket (width <= FRACTION_TOL x its
# top) with room for rounding
BESIDE = 0.95 * FRACTION_TOL


@dataclass
class Balance:
    """The outcome of one step.

    mode: 'move' (the base moves), 'rest' (the base creeps: slower than `creep`), 'fall'
    (the inertial wrench exceeds 1 % of the weight), 'air' (nothing touches the sand).
    xi: base twist (vx, vz, wy) at p, m/s and rad/s. rates: each leg's rate, rad/s.
    torques: each servo's torque about its axis, N m (stall torque for a stalled leg).
    stalled, slowed: per leg. residual: |(1)|'s imbalance, N (forces in N, the moment
    divided by L_c). inertial: |M (xi - xi_prev) / dt| the same way, N. bridge: how far the
    exact (unramped) RFT at xi is from the ramped one, N (a root on a jump: about one facet's
    force). leg_wrench: each leg's sand wrench (one leg); base_wrench.
    """

    mode: str
    xi: np.ndarray
    rates: np.ndarray
    torques: np.ndarray
    stalled: np.ndarray
    slowed: np.ndarray
    residual: float = 0.0
    inertial: float = 0.0
    bridge: float = 0.0
    leg_wrench: dict = field(default_factory=dict)
    base_wrench: np.ndarray = field(default_factory=lambda: np.zeros(3))
    converged: bool = True
    detail: str = ''


def scaling_of(posed: PosedMultibody) -> Scaling:
    """The scaled metric of the stack (predictor/live.py RobotPredictor): s_F = the weight, L_c."""
    return Scaling(posed.robot.weight, posed.robot.char_length)


def tether_wrench(tension: float, phi: float) -> np.ndarray:
    """Planar wrench of the tether at p: tension (N) along d(phi) = (-cos phi, sin phi)."""
    return tension * np.array([-math.cos(phi), math.sin(phi), 0.0])


def mass_matrix(posed: PosedMultibody) -> np.ndarray:
    """The base's planar mass matrix at p for twists (vx, vz, wy): kinetic energy
    m |v_c|^2 / 2 + I_c wy^2 / 2 with v_c = (vx + wy r_z, vz - wy r_x), r = c - p."""
    rob = posed.robot
    r = posed.com - posed.ref
    m = rob.mass
    return np.array([[m, 0.0, m * r[2]],
                     [0.0, m, -m * r[0]],
                     [m * r[2], -m * r[0], m * (r[0] ** 2 + r[2] ** 2) + rob.inertia]])


def record(bal: Balance, parts: list[Part], wrenches) -> None:
    """Store each part's wrench per leg (and the base's) and the servo torques."""
    for pt, w in zip(parts, wrenches):
        if pt.jac is None:
            bal.base_wrench = np.asarray(w, dtype=float)
            continue
        tau = pt.torque(w)
        for i in pt.legs:
            bal.leg_wrench[i] = np.asarray(w, dtype=float) / pt.count
            bal.torques[i] = tau


def step_balance(posed: PosedMultibody, model: StressModel, rates: np.ndarray, load: np.ndarray,
                 xi_prev: np.ndarray, dt: float, creep: float, backend: str = 'auto',
                 packs: dict | None = None, restarts: int = RESTARTS) -> Balance:
    """(1) at fixed leg rates (rad/s). load: gravity plus tether (N, N, N m about p).
    packs: the pose's bound parts, shared between calls at one pose (contact.Contact).
    restarts: how many random restarts (two ramp schedules each) follow the fixed starts."""
    n = len(posed.legs)
    rates = np.asarray(rates, dtype=float)
    bal = Balance('move', np.zeros(3), rates.copy(), np.zeros(n), np.zeros(n, bool),
                  np.zeros(n, bool))
    mm = mass_matrix(posed)
    robot = posed.robot
    w = robot.weight
    fscale = scaling_of(posed).diag
    contact = Contact(posed, model, rates, backend=backend, packs=packs)
    if not contact.any:
        # in the air: it falls with what it had, gravity and the tether adding
        bal.mode = 'air'
        bal.xi = xi_prev + dt * np.linalg.solve(mm, load)
        bal.inertial = float(np.linalg.norm(load / fscale)) * w
        return bal
    tips = [abs(pt.rate) for pt in contact.moving()]
    v_ref = max(max(tips, default=0.0) * robot.char_length,
                float(np.hypot(xi_prev[0], xi_prev[1])),
                abs(float(xi_prev[2])) * robot.char_length, 1e3 * creep)
    ts = np.array([v_ref, v_ref, v_ref / robot.char_length])
    m_dt = mm / dt
    # (W + load - M (xi - xi_prev) / dt) / (s_F, s_F, s_F L_c) = 0; each part rides along.
    # From the last twist first, then from rest (where a root far from the last twist lies,
    # e.g. a fall coming to rest, the ramps' first stages can lead the last twist astray).
    last = np.asarray(xi_prev, dtype=float) / ts
    a, b, c = np.diag(1.0 / fscale), -m_dt / fscale[:, None], (load + m_dt @ xi_prev) / fscale
    for x0, eps in _starts(last, lambda: (xi_prev + dt * np.linalg.solve(mm, load)) / ts,
                           restarts):
        root = affine_root(contact, x0, ts, a, b, c, NEWTON_TOL, creep=creep, eps=eps)
        if root.converged:
            break
    bal.xi = root.x * ts
    bal.residual = root.residual * w
    bal.bridge = root.bridge * w
    bal.converged = root.converged
    bal.inertial = float(np.linalg.norm(m_dt @ (bal.xi - xi_prev) / fscale)) * w
    if not root.converged:
        bal.detail = f'no balance found (|residual| {root.residual:.3g} x the weight)'
    record(bal, contact.parts, root.extra.reshape(-1, 3))
    speed = max(float(np.hypot(bal.xi[0], bal.xi[1])), abs(bal.xi[2]) * robot.char_length)
    if bal.inertial > 0.01 * w:
        bal.mode = 'fall'
    elif speed < creep:
        bal.mode = 'rest'
    return bal


def _starts(last: np.ndarray, falling: Callable[[], np.ndarray], restarts: int = RESTARTS
            ) -> Iterator[tuple[np.ndarray, tuple[float, ...]]]:
    """The root search's starting points (scaled twists) with their ramp schedules, in the
    order step_balance tries them: from the last twist, from rest, from a free fall
    (falling(): computed only if reached), then restarts around the last twist. A generator,
    because most steps converge from the first start and the sixteen restarts' draws are not
    free (~60 us a step); reached, they are the same draws in the same order every run."""
    yield last, EPS[0]
    yield np.zeros(3), EPS[0]
    yield falling(), EPS[0]
    yield last, EPS[1]
    yield np.zeros(3), EPS[1]
    yield last, EPS[2]
    yield last, EPS[3]
    rng = np.random.default_rng(0)      # restarts: the same ones every run
    spread = 0.3 * max(1.0, float(np.linalg.norm(last)))
    for _ in range(restarts):
        for e in (EPS[0], EPS[2]):
            yield last + spread * rng.normal(size=3), e


def balance(posed: PosedMultibody, model: StressModel, servo: ServoSpec, command: np.ndarray,
            load: np.ndarray, xi_prev: np.ndarray, dt: float, creep: float,
            backend: str = 'auto', packs: dict | None = None,
            prior: np.ndarray | None = None) -> Balance:
    """(1) with torque-limited servos (module doc). command: rate per leg, rad/s.

    A leg whose torque at its commanded rate exceeds the servo's line runs at the rate where
    the two meet: the largest fraction f of its command with |tau(f)| <= line(f |command|).
    The sand's torque on a leg depends on its rate through the body's response (the facets'
    directions mix the leg's turn and the base's twist), so f is searched: bracketed between
    a fraction known to be within the line and one known to exceed it, the first guess the
    speed the line allows at the full-rate torque, then regula falsi (Illinois: an end kept
    twice has its excess halved). The step keeps the largest fraction found within the line
    (0: stalled, held by its gear). packs: as in step_balance; the simulator passes one per
    pose, so a step it shortens and solves again reuses the bound parts.

    prior: each leg's rate (rad/s) the previous step settled on. The rate where torque and
    line meet moves little from one step to the next, so a leg the line refuses at its
    command tries that rate first, then the rate one tolerance beside it (above if it was
    within the line, below if not): two solves bracket the answer to FRACTION_TOL where the
    search from the full-rate guess takes six to twelve. A prior that misses hands the
    bracket it found to the search; the answer meets the same tolerance either way."""
    command = np.asarray(command, dtype=float)
    guess = _prior_fractions(command, prior)
    solved: dict[bytes, tuple[Balance, bool]] = {}
    packs = {} if packs is None else packs    # the pose's bound parts, by grouping of legs

    def solve(frac: np.ndarray, thorough: bool = False) -> Balance:
        """step_balance at these fractions of the command; thorough: with its random
        restarts (the answer the step may keep), else without (a probe of the search: where
        no balance exists, the sixteen restart searches cost ~2,000 RFT evaluations, a
        hundred converging solves' worth, and in the walk they found one for 2 % of the
        solves). The search can come back to fractions it has solved (the bracket's low end
        when it closes), and step_balance is a pure function of its inputs (its restarts are
        seeded), so those reuse the earlier Balance unless a thorough one is asked for where
        a probe found none."""
        key = frac.tobytes()
        if key in solved:
            bal, was = solved[key]
            if was or bal.converged or not thorough:
                return bal
        bal = step_balance(posed, model, frac * command, load, xi_prev, dt, creep, backend,
                           packs, RESTARTS if thorough else 0)
        solved[key] = bal, thorough
        return bal

    frac = np.where(command != 0.0, 1.0, 0.0)
    lo = np.zeros_like(frac)                 # fractions known to be within the line
    hi = np.full_like(frac, np.nan)          # fractions known to exceed it
    g_lo = np.full_like(frac, -1.0)          # excess torque (N m) at lo and hi
    g_hi = np.full_like(frac, np.nan)
    moved = np.zeros_like(frac)              # the end the last guess replaced: -1 lo, +1 hi
    bal = solve(frac, thorough=True)         # at full command: most steps' answer
    for _ in range(STALL_ITERATIONS):
        if bal.mode == 'air':
            break
        g = excess(servo, command, frac, bal.torques)
        ok = g <= 0.0
        if ok.all() and np.isnan(hi).all():
            # every leg within its line and none refused so far: nothing to search (most
            # steps; the bookkeeping below would end the loop with the same fractions)
            lo = frac
            break
        # Illinois: an end kept twice in a row has its excess halved, so the next guess moves
        # it. The torque flattens as the rate grows (concave in the rate), so plain regula
        # falsi keeps the low end for good and creeps down from above: in the walk it ran out
        # of searches with a leg at 5 % of its command where the line allowed 30-50 %
        # (docs/design/walk-burrow-physics.md, check 15).
        side = np.where(ok, -1.0, 1.0)
        again = side == moved
        g_hi = np.where(ok & again, 0.5 * g_hi, g_hi)
        g_lo = np.where(~ok & again & (lo > 0.0), 0.5 * g_lo, g_lo)
        moved = side
        lo, g_lo = np.where(ok, frac, lo), np.where(ok, g, g_lo)
        hi, g_hi = np.where(ok, hi, frac), np.where(ok, g_hi, g)
        new = next_fractions(servo, command, frac, bal.torques, lo, hi, g_lo, g_hi, guess)
        if np.array_equal(new, frac):
            break
        frac = new
        bal = solve(frac)
    if bal.mode != 'air' and not np.array_equal(frac, lo):
        # the search ended off its feasible end: the largest fraction known within the line
        frac = lo
    bal = solve(frac, thorough=True)
    bal.stalled = (command != 0.0) & (frac == 0.0)
    bal.slowed = (frac > 0.0) & (frac < 1.0)
    for i in np.flatnonzero(bal.stalled):
        bal.torques[i] = math.copysign(servo.stall_torque, command[i])
    return bal


def excess(servo: ServoSpec, command: np.ndarray, frac: np.ndarray, torques: np.ndarray
           ) -> np.ndarray:
    """Per leg, how far (N m) its torque exceeds the servo's line at its rate where the torque
    drives the motion; negative (within) otherwise and for resting legs."""
    out = np.full(len(command), -1.0)
    for i, c in enumerate(command):
        if frac[i] == 0.0 or c == 0.0:
            continue
        tau = torques[i]
        if tau * c > 0.0:
            out[i] = abs(tau) - servo.torque_limit(frac[i] * c) * (1.0 + 1e-9)
    return out


def _prior_fractions(command: np.ndarray, prior: np.ndarray | None) -> np.ndarray:
    """Each leg's prior rate as a fraction of its command; NaN where there is none to try (no
    prior, a leg at rest before, turning the other way, or at least as fast as commanded)."""
    out = np.full(len(command), np.nan)
    if prior is None:
        return out
    for i, c in enumerate(command):
        f = float(prior[i]) / c if c != 0.0 else 0.0
        if 0.0 < f < 1.0:
            out[i] = f
    return out


def next_fractions(servo: ServoSpec, command: np.ndarray, frac: np.ndarray, torques: np.ndarray,
                   lo: np.ndarray, hi: np.ndarray, g_lo: np.ndarray, g_hi: np.ndarray,
                   guess: np.ndarray | None = None) -> np.ndarray:
    """The next rate fraction per leg (balance). A leg never refused keeps its fraction. A
    refused one is searched inside (lo, hi): its guess (the prior rate as a fraction, NaN for
    none) first, then one tolerance above it if it was within the line or below it if not;
    after that, while nothing above 0 is known within the line, the speed the line allows at
    the torque just refused; once both ends are known, regula falsi on the excess torque,
    kept 5 % of the bracket away from its ends. A bracket narrower than FRACTION_TOL of its
    top ends the search at lo, and a leg refused below MIN_FRACTION of its command stalls
    (lo = 0)."""
    new = frac.copy()
    for i, c in enumerate(command):
        if c == 0.0 or math.isnan(hi[i]):
            continue
        width = hi[i] - lo[i]
        if width <= FRACTION_TOL * hi[i] or hi[i] <= MIN_FRACTION:
            new[i] = lo[i]
            continue
        p = math.nan if guess is None else guess[i]
        if lo[i] < p < hi[i]:            # not tried yet (a tried guess becomes an end)
            new[i] = p
            continue
        if p == lo[i]:                   # within the line: is one tolerance faster too?
            new[i] = min(p * (1.0 + BESIDE), 0.5 * (p + hi[i]))
            continue
        if p == hi[i] and lo[i] < p * (1.0 - BESIDE):   # refused: one tolerance slower?
            new[i] = p * (1.0 - BESIDE)
            continue
        if lo[i] > 0.0:
            f = lo[i] + width * (-g_lo[i]) / (g_hi[i] - g_lo[i])
        elif frac[i] == hi[i]:
            f = servo.speed_at(torques[i]) / abs(c)
        else:
            f = 0.5 * hi[i]
        new[i] = min(max(f, lo[i] + 0.05 * width), hi[i] - 0.05 * width)
    return new
