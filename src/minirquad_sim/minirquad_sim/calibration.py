"""Calibration of the power model against the paper's burrowing energy ratios.

The paper (section VI-B, Fig. 10(a)) measured the energy of 8 s of burrowing with the idle
power removed: DH and DL cost 1.32 and 1.26 times SH. The leg power model is linear in its
coefficients, E_mode = k_free A + k_sand S + k_hold H + k_contact C, with

    A = sum over legs of the integral of |w| dt          (rad)
    S = sum over legs of the integral of |w| d dt        (rad m)
    H = sum over legs of the integral of d dt            (m s)
    C = sum over legs of the time the tip is in the sand (s)

so with k_free and k_sand fixed (assumptions) the two ratios are two linear equations in
k_hold and k_contact. ``calibrate`` solves them; the results are the defaults in
``power.PowerModel`` and a test checks the simulated ratios.
"""
from __future__ import annotations

import numpy as np

from minirquad_driver.protocol.messages import BurrowMode
from rftgls_core.robots.measured_burrows import MEASURED_ENERGY_RATIOS

from .robot import SimRobot

WINDOW_S = 8.0
RATIOS = {m: MEASURED_ENERGY_RATIOS['minirquad'][m] for m in ('DH', 'DL')}   # relative to SH


def burrow_components(mode: str, window: float = WINDOW_S, dt: float = 0.01) -> np.ndarray:
    """(A, S, H, C) for one burrow sequence from standing, over ``window`` seconds."""
    robot = SimRobot()
    robot.burrow(BurrowMode[mode])
    acc = np.zeros(4)
    for _ in range(round(window / dt)):
        robot.step(dt)
        for s, d in zip(robot.servos, robot.depths()):
            w = abs(s.velocity)
            acc += (w * dt, w * d * dt, d * dt, dt if d > 0.0 else 0.0)
    return acc


def burrow_energy(mode: str, robot: SimRobot | None = None, window: float = WINDOW_S,
                  dt: float = 0.01) -> float:
    """Energy (J) above idle of one burrow sequence, from the full simulated power."""
    robot = robot or SimRobot()
    robot.burrow(BurrowMode[mode])
    e = 0.0
    for _ in range(round(window / dt)):
        robot.step(dt)
        e += (robot.power - robot.power_model.p_idle) * dt
    return e


def calibrate(k_free: float, k_sand: float) -> tuple[float, float]:
    """(k_hold W/m, k_contact W) giving the paper's DH/SH and DL/SH energy ratios."""
    comp = {m: burrow_components(m) for m in ('DH', 'DL', 'SH')}
    rows, rhs = [], []
    for mode, ratio in RATIOS.items():
        diff = comp[mode] - ratio * comp['SH']
        rows.append([diff[2], diff[3]])
        rhs.append(-(k_free * diff[0] + k_sand * diff[1]))
    k_hold, k_contact = np.linalg.solve(np.array(rows), np.array(rhs))
    return float(k_hold), float(k_contact)


if __name__ == '__main__':   # python -m minirquad_sim.calibration
    from .power import PowerModel
    pm = PowerModel()
    k_hold, k_contact = calibrate(pm.k_free, pm.k_sand)
    print(f'k_hold={k_hold:.6g} k_contact={k_contact:.6g}')
