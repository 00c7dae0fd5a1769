"""Print the wrench budget of a multibody run: at a few instants, each part's sand wrench
(Fx, Fz in N, My in N m about the tether point p, world axes), gravity, the servo torques
and the pose, so a reader sees which body carries the robot and which one turns it.

    python tools/wrench_budget.py burrow DH [--pull forward] [--sled KG] [--rows 24]
    python tools/wrench_budget.py walk 3

A diagnostic for docs/design/walk-burrow-physics.md; it calls the simulation's public API.
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from rftgls_core.multibody import simulate as sim_mod
from rftgls_core.multibody.gaits import TABLE_II_BURROWS as TABLE_II
from rftgls_core.multibody.gaits import BurrowGait, WalkGait
from rftgls_core.multibody.robot import from_preset
from rftgls_core.multibody.sled import Sled
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('what', choices=('burrow', 'walk'))
    ap.add_argument('arg', help='burrow mode (DH, DL, SH) or walk duration (s)')
    ap.add_argument('--pull', default='backward', choices=('backward', 'forward'))
    ap.add_argument('--sled', type=float, default=None, help='sled mass, kg')
    ap.add_argument('--rows', type=int, default=24)
    a = ap.parse_args()
    robot = from_preset(get_robot('minirquad'), a.pull)
    if a.what == 'burrow':
        retract, final = TABLE_II[a.arg]
        gait = BurrowGait(robot, (0.0, 0.0), tuple(map(math.radians, retract)),
                          tuple(map(math.radians, final)))
    else:
        gait = WalkGait(robot, duration=float(a.arg))
    sim = sim_mod.Simulator(robot, get_medium('m90_sand'),
                            sled=None if a.sled is None else Sled(a.sled))
    rows: list = []

    def record(_t: float) -> None:      # after every step of the simulation's own run loop
        b = sim.last
        posed = robot.pose(sim.pose, sim.q)
        legs = np.array([b.leg_wrench.get(i, np.zeros(3)) for i in range(len(robot.legs))])
        rows.append((sim.samples[-1], legs, np.asarray(b.base_wrench), posed.gravity.copy()))
    result = sim.run(gait, progress=record)
    status = f'{result.status.value} {result.reason}: {result.detail}'
    print(status)
    names = [leg.name.replace('_hip', '') for leg in robot.legs]
    print('t_s phase mode | p_x mm, h mm, thetaB deg | q deg | per leg (Fx, Fz, My) | base | '
          'gravity My | torques N m')
    for s, legs, base, grav in rows[::max(1, len(rows) // a.rows)] + rows[-1:]:
        legtxt = ' '.join(f'{n[:1].upper()}{n.split("_")[1][:1]}({w[0]:+.2f},{w[1]:+.2f},'
                          f'{w[2]:+.3f})' for n, w in zip(names, legs))
        print(f'{s.t:5.2f} {s.phase:7s} {s.mode:4s} | {s.px * 1e3:6.1f} {s.pz * 1e3:6.1f} '
              f'{math.degrees(s.theta_b):6.1f} | '
              + ' '.join(f'{math.degrees(v):6.1f}' for v in s.q)
              + f' | {legtxt} | base({base[0]:+.2f},{base[1]:+.2f},{base[2]:+.3f}) | '
              f'{grav[2]:+.3f} | ' + ' '.join(f'{v:+.3f}' for v in s.torques))


if __name__ == '__main__':
    main()
