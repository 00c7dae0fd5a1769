"""What one capacity estimate costs during a tug, and how far the lower bound's grids move it.

    python tools/tug_estimate_cost.py --phi-step-deg 0.5 --prefetch
    python tools/tug_estimate_cost.py --phi-step-deg 0          # the bound at the exact phi
    python tools/tug_estimate_cost.py --pitch-creep-deg 0.001 --theta-b-step-deg 0.1 --prefetch

Feeds capacity_node's estimator (the shipped ros2_ws/params/capacity_node.yaml, map and live
edge checks included) the sequence cycle 1 of `make demo`'s 600 g tug gives it: the planned
gait's pose held still (h 42.8 mm modelled with a 2.9 mm band, as replayed; theta_B 10.4 deg,
legs -20 deg; --pose) while the winch reels 0.5 mm per tension sample (50 mm/s at 100 Hz) from
0.605 m of tether (--rope-m) to 0.15 m, phi following the taut tether (rftgls_ros.tether: -3.1
deg to -12 deg, faster as the sled nears). --pitch-creep-deg turns the body by that much per
sample (the simulator's physics body under pre-tension: about -0.001 deg). Prints the
estimate's time (and with its prefetch) as percentiles and how many estimates took longer than
SLOW_MS, and with --compare-exact how far the grid bound lies from the exact bound at every
sample. No ROS.

    python tools/tug_estimate_cost.py --timeline --rope-m 0.754 --pose 44 10.3 -20 -20 \
        --pitch-creep-deg 0.001 --theta-b-step-deg 0.1

--timeline replays capacity_node's schedule on a virtual clock instead: a tension sample every
10 ms, the node answering the newest one when it is free (trigger_max_queue_s), each answer and
each prefetch (one, after every answer) costing the time they take here. It prints each
answer's evidence age before the next replaces it (the age behavior_node's 60 ms timeout
judges, less the ~5 ms from the MCU to the bridge) and how many exceed AGE_LIMIT_MS.
"""
from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from rftgls_core.types import Provenance
from rftgls_ros.capacity.estimator import JOINTS, CapacityEstimator
from rftgls_ros.capacity.node_predictor import predictor_from_params
from rftgls_ros.capacity.params import DEFAULTS, configs
from rftgls_ros.tether import TetherTracker

ROOT = Path(__file__).resolve().parents[1]
POSE = (0.0428, 0.181783, -0.349066, -0.349066)   # h m, theta_B, theta_L1, theta_L2 rad
H_BAND_M = 0.0029
ROPE_M, LEFT_M, REEL_PER_SAMPLE_M = 0.605, 0.15, 5e-4
SLOW_MS = 20.0        # two tension periods: an estimate this slow ages the evidence visibly
PERIOD_MS = 10.0      # tension samples at 100 Hz
AGE_LIMIT_MS = 55.0   # the 60 ms evidence timeout less the sample's way to the bridge (~5 ms)


def _estimator(step_rad: float, pitch_step_rad: float) -> CapacityEstimator:
    """capacity_node's estimator with the shipped parameters and these lower-bound grids."""
    shipped = yaml.safe_load((ROOT / 'ros2_ws/params/capacity_node.yaml').read_text())
    p = {**DEFAULTS, **shipped['/**/capacity_node']['ros__parameters'],
         'lower_bound_phi_step_rad': step_rad, 'lower_bound_theta_b_step_rad': pitch_step_rad}
    p['map_file'] = str(ROOT / p['map_file'])
    est_cfg, _ = configs(p)
    return CapacityEstimator(predictor_from_params(p), est_cfg)


def _tug(e: CapacityEstimator, pose: tuple[float, float, float, float], creep_rad: float,
         rope_m: float) -> tuple[int, Callable[[int], None]]:
    """(samples in the tug, a function applying sample k's inputs to e)."""
    h, pitch, l1, l2 = pose
    tether = TetherTracker(rope_length=rope_m)

    def apply(k: int) -> None:
        t = 0.01 * k
        tether.update(k * REEL_PER_SAMPLE_M)
        e.update_joints(t, dict(zip(JOINTS, (l1, l1, l2, l2))))
        e.update('pitch', t, pitch + creep_rad * k)
        e.update('height', t, h, Provenance.MODELLED, H_BAND_M)
        e.update('phi', t, tether.phi(h))
        e.update('tension', t, 2.943)
    return int((rope_m - LEFT_M) / REEL_PER_SAMPLE_M), apply


def run(step_rad: float, prefetch: bool, n: int | None, pitch_step_rad: float = 0.0,
        creep_rad: float = 0.0, pose: tuple[float, float, float, float] = POSE,
        rope_m: float = ROPE_M) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(estimate ms, estimate + prefetch ms, lower bound N) per tension sample of the tug (its
    first n samples, or all); pose: h m, theta_B, theta_L1, theta_L2 rad."""
    e = _estimator(step_rad, pitch_step_rad)
    total, apply = _tug(e, pose, creep_rad, rope_m)
    t_est, t_all, lower = [], [], []
    for k in range(total if n is None else min(n, total)):
        t = 0.01 * k
        apply(k)
        t0 = time.perf_counter()
        est = e.estimate(t)
        t1 = time.perf_counter()
        if prefetch:
            e.prefetch()
        t_est.append(t1 - t0)
        t_all.append(time.perf_counter() - t0)
        lower.append(est.capacity_lower_N)
    return np.array(t_est) * 1e3, np.array(t_all) * 1e3, np.array(lower, dtype=float)


def timeline(step_rad: float, pitch_step_rad: float, creep_rad: float,
             pose: tuple[float, float, float, float], rope_m: float) -> np.ndarray:
    """Each answer's evidence age before the next answer replaces it, ms, on a virtual clock
    (module doc)."""
    e = _estimator(step_rad, pitch_step_rad)
    total, apply = _tug(e, pose, creep_rad, rope_m)
    apply(0)
    e.estimate(0.0)           # the first answer loads and compiles: outside the timeline
    now, k_next, answered = PERIOD_MS, 1, []
    while k_next < total:
        newest = min(int(now // PERIOD_MS), total - 1)
        if newest < k_next:            # idle until the next sample
            now, newest = PERIOD_MS * k_next, k_next
        for k in range(k_next, newest + 1):
            apply(k)                   # every input is applied; the newest is answered
        t0 = time.perf_counter()
        e.estimate(0.01 * newest)
        now += 1e3 * (time.perf_counter() - t0)
        answered.append((newest, now))
        k_next = newest + 1
        t0 = time.perf_counter()
        e.prefetch()
        now += 1e3 * (time.perf_counter() - t0)
    return np.array([t1 - PERIOD_MS * k0 for (k0, _), (_, t1) in zip(answered, answered[1:])])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--phi-step-deg', type=float, default=0.5)
    ap.add_argument('--theta-b-step-deg', type=float, default=0.0)
    ap.add_argument('--pitch-creep-deg', type=float, default=0.0,
                    help='body pitch change per tension sample, deg')
    ap.add_argument('--pose', type=float, nargs=4, metavar=('H_MM', 'THETA_B', 'L1', 'L2'),
                    help='the held pose, mm and deg (default: the planned gait\'s, '
                         f'{POSE[0] * 1e3:.1f} mm, '
                         + ', '.join(f'{math.degrees(x):.1f}' for x in POSE[1:]) + ' deg)')
    ap.add_argument('--prefetch', action='store_true')
    ap.add_argument('--samples', type=int, default=None,
                    help='only the first N tension samples (default: the whole tug, 910)')
    ap.add_argument('--compare-exact', action='store_true',
                    help='also run the exact bound and report grid - exact, N')
    ap.add_argument('--rope-m', type=float, default=ROPE_M,
                    help=f'tether paid out at the start, m (default {ROPE_M}; the demo\'s 400 g '
                         'tug starts at 0.754)')
    ap.add_argument('--timeline', action='store_true',
                    help='replay capacity_node\'s schedule on a virtual clock (module doc)')
    a = ap.parse_args()
    creep = math.radians(a.pitch_creep_deg)
    pose = POSE if a.pose is None else (a.pose[0] * 1e-3, *map(math.radians, a.pose[1:]))
    if a.timeline:
        ages = timeline(math.radians(a.phi_step_deg), math.radians(a.theta_b_step_deg), creep,
                        pose, a.rope_m)
        q = np.percentile(ages, [50, 99])
        print(f'evidence age before replacement: median {q[0]:.1f} ms, 99 % {q[1]:.1f} ms, '
              f'max {ages.max():.1f} ms; {int(np.sum(ages > AGE_LIMIT_MS))} of {len(ages) + 1} '
              f'answers over {AGE_LIMIT_MS:g} ms')
        return
    t_est, t_all, lower = run(math.radians(a.phi_step_deg), a.prefetch, a.samples,
                              math.radians(a.theta_b_step_deg), creep, pose, a.rope_m)
    skip = 5   # the first estimates load and compile
    for name, t in (('estimate', t_est[skip:]), ('estimate + prefetch', t_all[skip:])):
        q = np.percentile(t, [50, 90, 99])
        print(f'{name}: median {q[0]:.2f} ms, 90 % {q[1]:.1f} ms, 99 % {q[2]:.1f} ms, '
              f'max {t.max():.1f} ms; {int(np.sum(t > SLOW_MS))} of {len(t)} over '
              f'{SLOW_MS:g} ms; {t.sum() * 1e-3:.1f} s of computing in a '
              f'{len(t) * 1e-2:.1f} s tug')
    if a.compare_exact:
        exact = run(0.0, False, a.samples, 0.0, creep, pose, a.rope_m)[2]
        d = lower - exact
        print(f'grid - exact lower bound: min {d.min():+.4f} N, max {d.max():+.4f} N '
              f'({int(np.sum(d > 0))} of {len(d)} samples above the exact bound)')


if __name__ == '__main__':
    main()
