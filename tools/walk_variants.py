"""Run the MiniRQuad walk with one modelling choice changed and print where it ends, so the
suspects of the walk's overturn can be checked one by one (docs/design/walk-burrow-physics.md,
check 14). A diagnostic: the model itself is not changed.

    python tools/walk_variants.py                          # nominal
    python tools/walk_variants.py --phases 0 0.5 0.5 0     # LH LF RH RF: a trot
    python tools/walk_variants.py --ff 0.1                 # MiniRHex's feed-forward as it runs
    python tools/walk_variants.py --kp 10 --cap 8          # the project firmware's clock loop
    python tools/walk_variants.py --xi-scale 4 --pull forward
    python tools/walk_variants.py --no-plate               # the base plate feels no sand

--ff scales the clock's feed-forward rate, --kp sets the MCU's position gain (1/s), --cap the
largest commanded leg rate (rad/s), --xi-scale multiplies the medium's stress scales,
--no-plate takes the base plate's facets out of the sand (the legs alone carry the robot;
the run then goes on with the plate below the surface, which the real robot cannot do).
"""
from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from rftgls_core.multibody import simulate as sim_mod
from rftgls_core.multibody.gaits import WalkGait
from rftgls_core.multibody.robot import from_preset
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot


class LoopVariant(sim_mod.Simulator):
    """The simulator with the MCU's loop changed: feed-forward times `ff`, rate capped at
    `cap` rad/s (the gain is SimOptions.kp). The commanded rate kp e + ff' is clipped by
    handing the base class a feed-forward that lands on the clipped value."""

    def __init__(self, *a, ff: float = 1.0, cap: float = math.inf, **kw):
        super().__init__(*a, **kw)
        self.ff_scale, self.cap = ff, cap

    def _substep(self, dt_max, q_ref, ff, tension, phi, phase, book=True):
        fb = self.options.kp * sim_mod.position_error(self.robot, q_ref, self.q)
        cmd = np.clip(np.asarray(ff, dtype=float) * self.ff_scale + fb, -self.cap, self.cap)
        return super()._substep(dt_max, q_ref, cmd - fb, tension, phi, phase, book)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--duration', type=float, default=8.0, help='s')
    ap.add_argument('--pull', default='backward', choices=('backward', 'forward'))
    ap.add_argument('--phases', type=float, nargs=4, metavar=('LH', 'LF', 'RH', 'RF'))
    ap.add_argument('--ff', type=float, default=1.0)
    ap.add_argument('--kp', type=float, default=sim_mod.SimOptions().kp)
    ap.add_argument('--cap', type=float, default=math.inf)
    ap.add_argument('--xi-scale', type=float, default=1.0)
    ap.add_argument('--no-plate', action='store_true')
    a = ap.parse_args()
    robot = from_preset(get_robot('minirquad'), a.pull)
    if a.no_plate:   # no base facets and no surface points: nothing stops the plate sinking
        robot = dataclasses.replace(robot, base=None, base_mesh=None,
                                    surface_points=np.zeros((0, 3)))
    kw = {} if a.phases is None else {'phases': dict(zip(('LH', 'LF', 'RH', 'RF'), a.phases))}
    gait = WalkGait(robot, duration=a.duration, **kw)
    m = get_medium('m90_sand')
    medium = dataclasses.replace(m, xi_n=m.xi_n * a.xi_scale, zeta=m.zeta * a.xi_scale)
    sim = LoopVariant(robot, medium, options=sim_mod.SimOptions(kp=a.kp), ff=a.ff, cap=a.cap)
    res = sim.run(gait)
    s0, s1 = res.samples[0], res.samples[-1]
    print(f'{res.status.value} {res.reason if res.status.value != "assumed" else ""} '
          f'{res.detail} | t {s1.t:.2f} s, p moved {(s1.px - s0.px) * 1e3:+.1f} mm, '
          f'h {s1.pz * 1e3:.1f} mm, thetaB {math.degrees(s1.theta_b):+.1f} deg')


if __name__ == '__main__':
    main()
