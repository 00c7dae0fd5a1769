"""Random streams of states for the warm-started `direct`: warm against cold at every message.

The generator behind tests/core/test_surfaces_warm.py's random-stream test and the large
count quoted on docs/design/warm-direct.md. Every stream: a random robot pose (h 0-45 mm,
body pitch +-15 deg, legs +-60 deg), a random drift over the stream (h +-3 mm, angles
+-5 deg), sensor noise (0.05 mm, 0.06 deg), a random pull (forward or backward) and angle
(+-40 deg); robots alternate MiniRQuad (M90 sand) and the prototype (glass beads).

Run as a script for the large count (a few minutes on one core):

    python tests/core/warm_streams.py --streams 100 --states 100 [--seed 0] [--json out.json]
        [--no-seed-check]

It prints every mismatch (capacity off by more than 1e-6 relative, or a different status),
the fallback rate and the reasons.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.types import AnchorState, Pull

RTOL = 1e-6
ROBOTS = ('minirquad', 'prototype')


def medium_of(robot: str) -> str:
    return 'glass_beads' if robot == 'prototype' else 'm90_sand'


def noisy(rng, base, n, drift=(0.0, 0.0, 0.0, 0.0), sigma=(5e-5, 1e-3, 1e-3, 1e-3)):
    """n states: base + drift * k / n + Gaussian sensor noise (m, rad)."""
    base, drift, sigma = (np.asarray(x, dtype=float) for x in (base, drift, sigma))
    return [AnchorState(*(base + drift * k / n + rng.normal(0.0, sigma))) for k in range(n)]


@dataclass
class Stream:
    """One random stream: robot, states, pull angle (rad) and pull."""

    robot: str
    states: list
    phi: float
    pull: Pull


def random_stream(rng: np.random.Generator, trial: int, n_states: int) -> Stream:
    robot = ROBOTS[trial % 2]
    base = (rng.uniform(0.0, 0.045), *np.radians(rng.uniform((-15, -60, -60), (15, 60, 60))))
    drift = (rng.uniform(-0.003, 0.003), *np.radians(rng.uniform(-5.0, 5.0, size=3)))
    pull = Pull.BACKWARD if rng.uniform() < 0.5 else Pull.FORWARD
    states = noisy(rng, base, n_states, drift=drift)
    return Stream(robot, states, math.radians(rng.uniform(-40.0, 40.0)), pull)


@dataclass
class StreamResult:
    """Warm against cold on one stream."""

    steps: int = 0
    fallbacks: int = 0
    reasons: Counter = field(default_factory=Counter)
    mismatches: list = field(default_factory=list)   # (k, state, rel, warm, cold details)


def compare(stream: Stream, **warm_options) -> StreamResult:
    """Warm and cold answers at every state of the stream; mismatches are recorded."""
    rob, med = get_robot(stream.robot), get_medium(medium_of(stream.robot))
    cold = RobotPredictor(rob, med, method='direct')
    warm = RobotPredictor(rob, med, method='direct-warm', surface_options=warm_options)
    out = StreamResult()
    for k, st in enumerate(stream.states):
        rw = warm.predict(st, stream.phi, stream.pull)
        rc = cold.predict(st, stream.phi, stream.pull)
        bad, rel = rw.status is not rc.status, 0.0
        if not bad and rc.capacity_N is not None:
            rel = abs(rw.capacity_N / rc.capacity_N - 1.0)
            bad = not rel <= RTOL
        if bad:
            out.mismatches.append({'k': k, 'state': [st.h, st.theta_b, st.theta_l1, st.theta_l2],
                                   'rel': rel, 'warm_status': rw.status.value,
                                   'cold_status': rc.status.value,
                                   'warm': rw.detail, 'cold': rc.detail})
    solver = warm.solver(stream.pull)
    out.steps, out.fallbacks = solver.n_steps_, solver.n_fallbacks_
    out.reasons = Counter(solver.fallback_reasons_)
    return out


def run(n_streams: int, n_states: int, seed: int = 0, verbose: bool = True,
        **warm_options) -> dict:
    """n_streams random streams of n_states from one generator seeded `seed`."""
    rng = np.random.default_rng(seed)
    steps = falls = 0
    reasons: Counter = Counter()
    mismatches = []
    t0 = time.perf_counter()
    for trial in range(n_streams):
        stream = random_stream(rng, trial, n_states)
        r = compare(stream, **warm_options)
        steps, falls = steps + r.steps, falls + r.fallbacks
        reasons.update(r.reasons)
        for m in r.mismatches:
            m.update(trial=trial, robot=stream.robot, pull=stream.pull.value, phi=stream.phi)
            mismatches.append(m)
            if verbose:
                print(f"MISMATCH trial {trial} ({stream.robot}) step {m['k']}: rel "
                      f"{m['rel']:.3g} {m['warm_status']}/{m['cold_status']}\n"
                      f"  warm: {m['warm']}\n  cold: {m['cold']}", flush=True)
        if verbose:
            print(f'stream {trial + 1}/{n_streams} ({stream.robot}): fallbacks '
                  f'{r.fallbacks}/{r.steps}, {time.perf_counter() - t0:.0f} s', flush=True)
    return {'streams': n_streams, 'states': n_states, 'seed': seed, 'messages': steps,
            'fallbacks': falls, 'fallback_rate': falls / steps if steps else math.nan,
            'reasons': dict(reasons), 'mismatches': mismatches,
            'seconds': time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--streams', type=int, default=100)
    ap.add_argument('--states', type=int, default=100)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--json', default='')
    ap.add_argument('--no-seed-check', action='store_true',
                    help="WarmDirect(seed_check=False): the warm step without the cold seeds")
    a = ap.parse_args(argv)
    res = run(a.streams, a.states, a.seed, seed_check=not a.no_seed_check)
    print(f"{res['messages']} messages, {len(res['mismatches'])} mismatches, fallback rate "
          f"{res['fallback_rate']:.3f}, {res['seconds']:.0f} s\nreasons: {res['reasons']}")
    if a.json:
        with open(a.json, 'w') as f:
            json.dump(res, f, indent=1, default=str)
    return 1 if res['mismatches'] else 0


if __name__ == '__main__':
    sys.exit(main())
