"""Live figures: warm-started `direct` per message over a stream of MiniRQuad states, every call
timed (median and p99, wall and thread CPU), against the cold `direct` on a sample of them."""
from __future__ import annotations

import math
import time

import numpy as np

from ..predictor.live import RobotPredictor
from ..rft.media import get_medium
from ..robots.presets import minirquad
from ..types import AnchorState, Pull
from .engine import TYPICAL_STATE
from .timing import Figure

# The live stream: a MiniRQuad message stream at the DH pose, 1,000 states, burrowing slowly
# (p 1 mm deeper, proximal legs 2 deg further in over the stream: 2 s at 500 Hz) under sensor
# noise (h 0.05 mm, angles 0.06 deg, one sigma), pulled at phi = -20 deg.
LIVE_STATES = 1000
LIVE_PHI = math.radians(-20.0)
LIVE_DRIFT = (-0.001, 0.0, math.radians(-2.0), 0.0)
LIVE_SIGMA = (5e-5, math.radians(0.06), math.radians(0.06), math.radians(0.06))


# A parked stream: the 600 g sled's anchor in `make demo` as the physics burrow left it
# (capacity_node's state through the tug: h m, theta_B, theta_L1, theta_L2 rad), the tether
# angle creeping 0.01 deg per message from -8 deg. Next to this pose a facet switches beside
# the root, and most warm attempts are refused (surfaces/warm.py, patience).
PARKED_STATE = AnchorState(0.043278, math.radians(10.9), math.radians(-20.0), math.radians(-20.0))
PARKED_PHIS = np.radians(-8.0 - 0.01 * np.arange(300))


def live_stream(n: int = LIVE_STATES, seed: int = 16) -> list[AnchorState]:
    """The states of the live benchmark (see LIVE_DRIFT, LIVE_SIGMA), SI."""
    rng = np.random.default_rng(seed)
    base = np.array(TYPICAL_STATE.as_tuple())
    drift, sigma = np.array(LIVE_DRIFT), np.array(LIVE_SIGMA)
    return [AnchorState(*(base + drift * k / n + rng.normal(0.0, sigma))) for k in range(n)]


def live_figures() -> list[Figure]:
    """Warm-started direct over the live stream, every state timed (median and p99 of the
    calls, not best-of), against the cold direct on a sample of the same states."""
    robot, medium = minirquad(), get_medium('m90_sand')
    states = live_stream()
    warm = RobotPredictor(robot, medium, method='direct-warm')
    cold = RobotPredictor(robot, medium, method='direct')
    warm.predict(states[0], LIVE_PHI, Pull.BACKWARD)   # compile and cache, then start afresh
    warm = RobotPredictor(robot, medium, method='direct-warm')
    times, cpu = [], []
    for st in states:
        c0, t0 = time.thread_time(), time.perf_counter()
        warm.predict(st, LIVE_PHI, Pull.BACKWARD)
        times.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    t_cold = []
    for st in states[::20]:
        t0 = time.perf_counter()
        cold.predict(st, LIVE_PHI, Pull.BACKWARD)
        t_cold.append(time.perf_counter() - t0)
    us = np.sort(np.asarray(times)) * 1e6
    solver = warm.solver(Pull.BACKWARD)
    parked = RobotPredictor(robot, medium, method='direct-warm')
    t_parked = []
    for phi in PARKED_PHIS:
        c0 = time.thread_time()
        parked.predict(PARKED_STATE, float(phi), Pull.BACKWARD)
        t_parked.append(time.thread_time() - c0)
    stuck = parked.solver(Pull.BACKWARD)
    what = f'{len(states)} MiniRQuad states near DH, noise and slow burrowing'
    return [
        Figure('capacity_live_warm_us_median', float(np.median(us)), 'us', budget='<= 1000',
               note=f'warm-started direct per message, {what}'),
        Figure('capacity_live_warm_us_p99', float(np.percentile(us, 99)), 'us',
               budget='<= 5000', note='same stream'),
        Figure('capacity_live_fallback_rate', solver.fallback_rate_, '',
               note=f'cold solves / messages (the first is cold); '
                    f'{dict(solver.fallback_reasons_)}'),
        Figure('capacity_live_cold_us_median', 1e6 * float(np.median(t_cold)), 'us',
               note=f'cold direct on every 20th state of the same stream ({len(t_cold)})'),
        # CPU time of the calling thread: what the call costs without the waits a shared
        # machine adds to the wall time (the warm steps run the kernel on this thread only).
        Figure('capacity_live_warm_cpu_us_median', 1e6 * float(np.median(cpu)), 'us',
               note='same calls, thread CPU time'),
        Figure('capacity_live_warm_cpu_us_p99', 1e6 * float(np.percentile(cpu, 99)), 'us',
               note='same calls, thread CPU time'),
        # The mean: a parked stream's calls are a mix of warm steps and cold solves.
        Figure('capacity_live_parked_cpu_us_mean', 1e6 * float(np.mean(t_parked)), 'us',
               note=f'{len(PARKED_PHIS)} messages at a pose parked next to a jump (the demo\'s '
                    f'600 g tug), thread CPU time; {dict(stuck.fallback_reasons_)}'),
    ]
