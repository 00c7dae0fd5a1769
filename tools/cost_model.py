"""Work per query of each mode, for predicting what runs onboard at which rate.

    python tools/cost_model.py [--states 200]

Counts, on this machine, per query: facet-twist pairs through the RFT kernels and wrench
calls (engine.BuriedBody), and the time, split into the kernels' share and the rest (Python
and small numpy calls: posing, the solvers' bookkeeping). The rest is also given in units of
one small numpy call (`numpy_call_us` of this run, a (5, 3) row normalisation), the unit a
slower interpreter scales. A CPU whose float64 multiply-add peak is P GFLOP/s (the bench's
peak_gflops_1core) and whose small numpy call takes c us then needs about

    pairs x flops_per_pair / (share x P) + rest_calls x c

per query, share being the kernels' share of peak (~0.5 here; docs/design/performance.md).
Modes: map query (no RFT), warm live step, cold `direct`, `twist-mesh` from scratch, and a
map build's state (prototype paper grid, both pulls, five angles, margins).
"""
from __future__ import annotations

import argparse
import time

import numpy as np


class _Counter:
    """Counts kernel pairs and calls, and the kernel time (thread CPU), of BuriedBody."""

    def __init__(self):
        from rftgls_core.rft import engine
        self.engine = engine
        self.pairs = self.calls = 0
        self.kernel_s = 0.0
        self._orig = engine._run_fused

        def run(parallel, serial, k, t, out):
            self.pairs += k['w'].shape[0] * t.shape[0]
            self.calls += 1
            t0 = time.thread_time()
            self._orig(parallel, serial, k, t, out)
            self.kernel_s += time.thread_time() - t0
        engine._run_fused = run

    def measure(self, fn, n: int) -> dict:
        self.pairs = self.calls = 0
        self.kernel_s = 0.0
        t0 = time.thread_time()
        for i in range(n):
            fn(i)
        total = time.thread_time() - t0
        return {'pairs': self.pairs / n, 'calls': self.calls / n, 'total_us': total / n * 1e6,
                'kernel_us': self.kernel_s / n * 1e6}


def numpy_call_us(repeats: int = 2000) -> float:
    """Median thread time of one small numpy call (a (5, 3) row normalisation), us."""
    x = np.random.default_rng(0).normal(size=(5, 3))
    times = []
    for _ in range(repeats):
        t0 = time.thread_time_ns()
        x / np.linalg.norm(x, axis=1, keepdims=True)
        times.append(time.thread_time_ns() - t0)
    return float(np.median(times)) / 1e3


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--states', type=int, default=200)
    args = p.parse_args(argv)
    from rftgls_core.benchmarks.live import LIVE_PHI, live_stream
    from rftgls_core.benchmarks.machine import describe, machine_record, peak_gflops
    from rftgls_core.maps.build import BuildSpec, solve_chunk
    from rftgls_core.maps.grid import prototype_grid
    from rftgls_core.maps.query import CapacityMap
    from rftgls_core.maps.shipped import SHIPPED, maps_dir
    from rftgls_core.predictor.live import RobotPredictor
    from rftgls_core.rft import kernels
    from rftgls_core.rft.media import get_medium
    from rftgls_core.robots.presets import minirquad
    from rftgls_core.types import Pull

    kernels.set_threads(1)
    count = _Counter()
    robot, medium = minirquad(), get_medium('m90_sand')
    stream = live_stream(args.states)
    phi = LIVE_PHI
    rows = {}

    cmap = CapacityMap.load(maps_dir() / SHIPPED['prototype'])
    g = cmap.grid
    rng = np.random.default_rng(0)
    lo = np.array([a[0] for a in g.axes])
    hi = np.array([a[-1] for a in g.axes])
    from rftgls_core.types import AnchorState
    qs = [AnchorState(*map(float, x)) for x in lo + (hi - lo) * rng.random((args.states, 4))]
    rows['map query'] = count.measure(lambda i: cmap.query(qs[i], -0.2, 'backward'), len(qs))

    warm = RobotPredictor(robot, medium, method='direct-warm')
    warm.predict(stream[0], phi, Pull.BACKWARD)   # compile and cache, then start afresh
    warm = RobotPredictor(robot, medium, method='direct-warm')
    rows['warm live step'] = count.measure(
        lambda i: warm.predict(stream[i], phi, Pull.BACKWARD), len(stream))
    cold = RobotPredictor(robot, medium, method='direct')
    sample = stream[::10]
    rows['cold direct'] = count.measure(
        lambda i: cold.predict(sample[i], phi, Pull.BACKWARD), len(sample))
    mesh = RobotPredictor(robot, medium, method='twist-mesh')
    rows['twist-mesh'] = count.measure(
        lambda i: mesh.predict(sample[i], phi, Pull.BACKWARD), len(sample))
    grid = prototype_grid()
    spec = BuildSpec(robot='prototype', medium=get_medium('glass_beads'))
    ks = np.linspace(0, grid.n_states - 1, max(10, args.states // 5)).astype(int)
    solve_chunk(spec, grid, ks[:1])
    rows['map build state'] = count.measure(lambda i: solve_chunk(spec, grid, ks[i:i + 1]),
                                            len(ks))

    call_us = numpy_call_us()
    peak = peak_gflops(1)
    print(describe(machine_record()))
    print(f'peak_gflops_1core {peak:.1f}; one small numpy call {call_us:.2f} us (thread CPU)')
    print(f'{"mode":<16} {"pairs":>9} {"calls":>6} {"total":>10} {"kernels":>10} '
          f'{"rest":>10} {"rest/call":>9}')
    for name, r in rows.items():
        rest = r['total_us'] - r['kernel_us']
        print(f'{name:<16} {r["pairs"]:>9.3g} {r["calls"]:>6.1f} {r["total_us"]:>8.0f}us '
              f'{r["kernel_us"]:>8.0f}us {rest:>8.0f}us {rest / call_us:>9.0f}')
    print('per query, thread CPU time; map build state = one state of the prototype paper '
          'grid (2 pulls x 5 angles), its edge pass not included')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
