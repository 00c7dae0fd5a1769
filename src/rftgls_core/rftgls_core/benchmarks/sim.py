"""Benchmarks of the whole-robot simulation (`rftgls bench --only sim`): one 8 s burrow and one
8 s walk of MiniRQuad on one core, and the cost per step against the leg mesh (facets) and the
step count. Figures are best of a few runs (timing.py), after a warm-up that compiles the
kernels. On request only (`--only sim`): the walk alone takes minutes."""
from __future__ import annotations

import math

from ..multibody.gaits import BurrowGait, WalkGait
from ..multibody.robot import from_preset
from ..multibody.simulate import SimOptions, Simulator
from ..multibody.sled import Sled
from ..rft import kernels
from ..rft.media import get_medium
from ..robots.presets import get_robot
from .timing import Figure, best_time

# The deep, high-capacity burrow of the paper's Table II (DH), tied to a 400 g sled (untethered
# it overturns after 3.2 s: docs/design/walk-burrow-physics.md; tethered it runs the whole 8 s),
# and MiniRHex's walk.
DH = ((-75.0, -50.0), (-40.0, 30.0))
SLED_KG = 0.4


def _burrow(n_arc: int = 24, dt: float = 0.02, joint_deg: float = 1.0):
    robot = from_preset(get_robot('minirquad', n_arc))
    gait = BurrowGait(robot, (0.0, 0.0), tuple(map(math.radians, DH[0])),
                      tuple(map(math.radians, DH[1])))
    opts = SimOptions(dt=dt, joint_step=math.radians(joint_deg))
    return lambda: Simulator(robot, get_medium('m90_sand'), options=opts,
                             sled=Sled(SLED_KG)).run(gait)


def _walk():
    robot = from_preset(get_robot('minirquad'))
    gait = WalkGait(robot, duration=8.0)
    return lambda: Simulator(robot, get_medium('m90_sand')).run(gait)


def _span(res) -> str:
    """How much of the gait a run simulated, and how it ended."""
    t = res.samples[-1].t if res.samples else 0.0
    end = '' if res.ok else f' ({res.reason})'
    return f'{t:.1f} of {res.duration_s:.0f} s simulated{end}'


def sim_figures() -> list[Figure]:
    before = kernels.threads()
    if kernels.AVAILABLE:
        kernels.set_threads(1)
    try:
        burrow = _burrow()
        res = burrow()                                   # warm-up: compiles, fills caches
        t_b = best_time(burrow, repeats=2)
        steps_b = len(res.samples)
        walk = _walk()
        res_w = walk()
        t_w = best_time(walk, repeats=1)
        steps_w = len(res_w.samples)
        figs = [Figure('sim_burrow_ms', 1e3 * t_b, 'ms', budget='<= 500 (one core)',
                       note=f'MiniRQuad DH burrow tied to a 400 g sled, {_span(res)}, '
                            f'{steps_b} steps, one core'),
                Figure('sim_walk_ms', 1e3 * t_w, 'ms', budget='<= 2000 (one core)',
                       note=f'MiniRQuad walk (MiniRHex clock, amble), {_span(res_w)}, '
                            f'{steps_w} steps'),
                Figure('sim_burrow_us_per_step', 1e6 * t_b / steps_b, 'us', note='DH burrow'),
                Figure('sim_walk_us_per_step', 1e6 * t_w / steps_w, 'us', note='walk')]
        for n_arc in (12, 48):
            run = _burrow(n_arc=n_arc)
            r = run()
            t = best_time(run, repeats=1)
            figs.append(Figure(f'sim_burrow_us_per_step_{n_arc}seg', 1e6 * t / len(r.samples),
                               'us', note=f'DH burrow, {n_arc} arc segments per leg '
                                          '(24 by default): cost against facets'))
        run = _burrow(joint_deg=0.5, dt=0.01)
        r = run()
        t = best_time(run, repeats=1)
        figs.append(Figure('sim_burrow_ms_half_steps', 1e3 * t, 'ms',
                           note=f'DH burrow with 0.5 deg / 10 ms steps ({len(r.samples)} steps): '
                                'cost against steps'))
        return figs
    finally:
        if kernels.AVAILABLE:
            kernels.set_threads(before)
