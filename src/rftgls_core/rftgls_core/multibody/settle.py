"""Settling under the weight: the robot lowered into the sand as by a crane at its centre of
mass, until the sand carries all of it.

A robot put down on sand sinks until its buried parts hold its weight. Quasi-statically that
is a lowering: a vertical force T_c at the centre of mass c (a crane, no moment) lets the
robot down at a steady rate while the sand takes over the rest of the weight. With all legs
held, the sand wrench at the base twist xi must then be a vertical force through c,

    Fx(xi) = 0,   M_c(xi) = 0,   v_z(c; xi) = -v_c                    (3 equations, xi)

and the crane carries T_c = m g - Fz(xi). The twist is the one at which the sand's limit
surface meets the ray along the weight (the trajectory method's slip twist under the weight).
The root is seeded from a scan of twist directions that lower c (the best-aligned sand
wrench), since the lowering twist can be far from straight down: C-legs pushed down also
push sideways, and the body slides and pitches as it sinks. The robot has settled where T_c
reaches zero.

A robot put down level (`level_depth`) sinks until the sand holds it; that first pose is
found by bisection on the depth with the resting check (support.rests), because a body that
only just touches the sand has lowering twists that meet no resistance at all (every buried
facet trails) and the lowering is not defined there.
"""
from __future__ import annotations

import numpy as np

from ..surfaces.sampling import fibonacci_sphere
from .contact import Contact
from .robot import PosedMultibody
from .roots import closure_root

NEWTON_TOL = 1e-11
SCAN_TWISTS = 400
SEEDS = 4


def lowering(contact: Contact, posed: PosedMultibody, guess: np.ndarray | None = None
             ) -> tuple[np.ndarray, float, list[np.ndarray], bool]:
    """(xi, crane force T_c in N, each part's wrench (contact.parts order), converged).

    xi is per unit lowering rate of c (v_c = 1 m/s; RFT is rate independent), so a lowering
    of c by h metres moves the base by xi * h."""
    robot = posed.robot
    w = robot.weight
    lc = robot.char_length
    r = posed.com - posed.ref

    def f(x: np.ndarray, eps: float = 0.0) -> np.ndarray:
        xi = x * np.array([1.0, 1.0, 1.0 / lc])
        # each part's wrench rides along: the shares at the closure point
        per = [pt.smooth_wrenches(xi, eps) if eps else pt.wrenches(xi) for pt in contact.parts]
        wr = np.sum(per, axis=0)
        m_c = wr[:, 2] - (r[2] * wr[:, 0] - r[0] * wr[:, 1])
        vz_c = xi[:, 1] - xi[:, 2] * r[0]
        return np.column_stack([wr[:, 0] / w, m_c / (w * lc), vz_c + 1.0] + per)

    seeds = [] if guess is None else [guess * np.array([1.0, 1.0, lc])]
    root = None
    for x0 in seeds + _seeds(f, r, lc):
        root = closure_root(f, x0, NEWTON_TOL)
        if root.converged:
            break
    assert root is not None
    xi = root.x * np.array([1.0, 1.0, 1.0 / lc])
    parts = list(root.extra.reshape(-1, 3))
    fz = float(sum(p[1] for p in parts))
    return xi, w - fz, parts, root.converged


_SCAN = fibonacci_sphere(SCAN_TWISTS)


def _seeds(f, r: np.ndarray, lc: float, count: int = SEEDS) -> list[np.ndarray]:
    """The scanned twists (lowering c) whose sand wrench is closest to a vertical force
    through c, best first (at most `count`, a few degrees apart), each scaled to lower c at
    unit rate (f's scaled units)."""
    # scan twists given at c, (vx_c, vz_c, wy L_c), moved to p: v_p = v_c + w x (p - c)
    wy = _SCAN[:, 2] / lc
    x = np.column_stack([_SCAN[:, 0] - wy * r[2], _SCAN[:, 1] + wy * r[0], _SCAN[:, 2]])
    down = np.flatnonzero(_SCAN[:, 1] < -1e-3)
    fx = f(x[down])
    # columns: Fx / W, M_c / (W L_c), the rate constraint, then (Fx, Fz, My) per part in N
    fz = fx[:, 4::3].sum(axis=1)
    off = np.where(fz > 0.0, np.hypot(fx[:, 0], fx[:, 1]) / np.maximum(fz, 1e-300), np.inf)
    out: list[np.ndarray] = []
    for k in np.argsort(off):
        if not np.isfinite(off[k]) or len(out) == count:
            break
        t = _SCAN[down[k]]
        if all(float(t @ u) < 0.995 for u in (_SCAN[down[j]] for j in out)):
            out.append(int(k))
    return [x[down[k]] / -_SCAN[down[k], 1] for k in out]


def level_depth(held, z_touch: float, step: float = 5e-3, max_depth: float = 0.15,
                iterations: int = 14) -> float:
    """Height z of the base at which a level robot first holds (bisection): held(z) -> bool,
    z_touch the height at which its lowest point touches the sand."""
    lo, hi = z_touch, z_touch - step
    while not held(hi):
        lo, hi = hi, hi - step
        if z_touch - hi > max_depth:
            raise ValueError(f'the robot sinks more than {max_depth * 1e3:.0f} mm without '
                             'the sand holding its weight')
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if held(mid):
            hi = mid
        else:
            lo = mid
    return hi
