"""The engine against its numpy reference path, side by side in one run.

    python tools/side_by_side.py [--rounds 5] [--cpu x86-64-v3]

Each workload runs once on the fused numba kernels (backend 'auto') and once on the numpy
path (backend 'numpy'), alternating, `--rounds` times; the table gives the best time of each,
their ratio, and how far the two answers are apart (the numpy path is the reference the
kernels are tested against; rftgls_core/rft/engine.py). Workloads:

  gls_cloud      MiniRQuad DH pose, 1,000 planar unit twists: pose, cull, mirror, wrenches
  sphere_6d      5,120-facet buried sphere x 1,000 random 6D twists, one thread
  direct_cold    `direct` from scratch at the DH pose (phi = -20 deg): pose, RFT, solve
  live_warm      warm-started `direct` over 200 states of the live stream (mean per state)

`--cpu x86-64-v3` runs the script again as a Zen 3 class CPU compiles and dispatches
(rftgls_core/benchmarks/machine.py); the first line names the machine either way.
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys

import numpy as np


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def workloads():
    from rftgls_core.benchmarks.engine import TYPICAL_STATE, sphere_workload, threads, unit_twists
    from rftgls_core.benchmarks.live import LIVE_PHI, live_stream
    from rftgls_core.predictor.live import RobotPredictor
    from rftgls_core.rft.engine import BuriedBody
    from rftgls_core.rft.media import get_medium
    from rftgls_core.rft.models import make_model
    from rftgls_core.robots.presets import minirquad
    from rftgls_core.types import Pull

    robot, medium = minirquad(), get_medium('m90_sand')
    model = make_model('agarwal', medium)
    planar = unit_twists(1000, robot.char_length)

    def cloud(backend):
        posed = robot.pose(TYPICAL_STATE, Pull.BACKWARD)
        return BuriedBody(posed.facets, model, ref=posed.ref, mirror_y=posed.mirror_y,
                          backend=backend).planar_wrench(planar)

    spheres = {b: sphere_workload(backend=b) for b in ('auto', 'numpy')}

    def sphere(backend):
        body, twists = spheres[backend]
        with threads(1):
            return body.wrench(twists)

    cold = {b: RobotPredictor(robot, medium, method='direct', backend=b)
            for b in ('auto', 'numpy')}

    def direct(backend):
        r = cold[backend].predict(TYPICAL_STATE, math.radians(-20.0), Pull.BACKWARD)
        return [r.capacity_N]

    stream = live_stream(200)

    def live(backend):
        warm = RobotPredictor(robot, medium, method='direct-warm', backend=backend)
        return [warm.predict(s, LIVE_PHI, Pull.BACKWARD).capacity_N for s in stream]

    return {'gls_cloud': (cloud, 1), 'sphere_6d': (sphere, 1), 'direct_cold': (direct, 1),
            'live_warm': (live, len(stream))}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--rounds', type=int, default=5)
    p.add_argument('--cpu', choices=('x86-64-v3', 'x86-64-v2'))
    args = p.parse_args(argv)
    from rftgls_core.benchmarks.machine import CPU_TARGETS, describe, machine_record
    from rftgls_core.benchmarks.timing import best_times_alternating
    if args.cpu and os.environ.get('RFTGLS_BENCH_CPU_TARGET') != args.cpu:
        env = {**os.environ, **CPU_TARGETS[args.cpu], 'RFTGLS_BENCH_CPU_TARGET': args.cpu}
        return subprocess.call([sys.executable, __file__, '--rounds', str(args.rounds),
                                '--cpu', args.cpu], env=env)
    print(describe(machine_record()) + f'; target {args.cpu or "native"}')
    print(f'{"workload":<12} {"numba":>11} {"numpy":>11} {"ratio":>7}  answers apart (rel.)')
    for name, (fn, per) in workloads().items():
        out: dict = {}
        calls = {b: (lambda b=b, fn=fn, out=out: out.__setitem__(b, fn(b)))
                 for b in ('auto', 'numpy')}
        best = best_times_alternating(calls, args.rounds)
        fast, ref = best['auto'] / per, best['numpy'] / per
        print(f'{name:<12} {_fmt(fast):>11} {_fmt(ref):>11} {ref / fast:>6.1f}x  '
              f'{_rel(out["auto"], out["numpy"]):.1e}')
    print(f'load average {os.getloadavg()[0]:.2f} at the end; best of {args.rounds} '
          'alternating rounds; live_warm is per state')
    return 0


def _fmt(seconds: float) -> str:
    return f'{seconds * 1e3:.3g} ms' if seconds >= 1e-3 else f'{seconds * 1e6:.3g} us'


if __name__ == '__main__':
    sys.exit(main())
