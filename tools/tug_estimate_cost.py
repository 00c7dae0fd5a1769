"""What one capacity estimate costs during a tug, and how far the lower bound's grids move it.

    python tools/tug_estimate_cost.py --phi-step-deg 0.5 --prefetch
    python tools/tug_estimate_cost.py --phi-step-deg 0          # the bound at the exact phi
    python tools/tug_estimate_cost.py --pitch-creep-deg 0.001 --theta-b-step-deg 0.1 --prefetch

Feeds capacity_node's estimator (the shipped ros2_ws/params/capacity_node.yaml, map and live
edge checks included) the sequence cycle 1 of `make demo`'s 600 g tug gives it: the planned
gait's pose held still (h 42.8 mm modelled with a 2.9 mm band, as replayed; theta_B 10.4 deg,
legs -20 deg) while the winch reels 0.5 mm per tension sample (50 mm/s at 100 Hz) from
0.605 m of tether to 0.15 m, phi following the taut tether (rftgls_ros.tether: -3.1 deg to
-12 deg, faster as the sled nears). --pitch-creep-deg turns the body by that much per
sample (the simulator's physics body under pre-tension: about -0.001 deg). Prints the
estimate's time (and with its prefetch) as percentiles and how many estimates took longer
than SLOW_MS, and with --compare-exact how far the grid bound lies from the exact bound at
every sample. No ROS.
"""
from __future__ import annotations

import argparse
import math
import time
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


def run(step_rad: float, prefetch: bool, n: int | None, pitch_step_rad: float = 0.0,
        creep_rad: float = 0.0, pose: tuple[float, float, float, float] = POSE
        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(estimate ms, estimate + prefetch ms, lower bound N) per tension sample of the tug (its
    first n samples, or all); pose: h m, theta_B, theta_L1, theta_L2 rad."""
    shipped = yaml.safe_load((ROOT / 'ros2_ws/params/capacity_node.yaml').read_text())
    p = {**DEFAULTS, **shipped['/**/capacity_node']['ros__parameters'],
         'lower_bound_phi_step_rad': step_rad, 'lower_bound_theta_b_step_rad': pitch_step_rad}
    p['map_file'] = str(ROOT / p['map_file'])
    est_cfg, _ = configs(p)
    e = CapacityEstimator(predictor_from_params(p), est_cfg)
    h, pitch, l1, l2 = pose
    tether = TetherTracker(rope_length=ROPE_M)
    total = int((ROPE_M - LEFT_M) / REEL_PER_SAMPLE_M)
    t_est, t_all, lower = [], [], []
    for k in range(total if n is None else min(n, total)):
        t = 0.01 * k
        tether.update(k * REEL_PER_SAMPLE_M)
        e.update_joints(t, dict(zip(JOINTS, (l1, l1, l2, l2))))
        e.update('pitch', t, pitch + creep_rad * k)
        e.update('height', t, h, Provenance.MODELLED, H_BAND_M)
        e.update('phi', t, tether.phi(h))
        e.update('tension', t, 2.943)
        t0 = time.perf_counter()
        est = e.estimate(t)
        t1 = time.perf_counter()
        if prefetch:
            e.prefetch()
        t_est.append(t1 - t0)
        t_all.append(time.perf_counter() - t0)
        lower.append(est.capacity_lower_N)
    return np.array(t_est) * 1e3, np.array(t_all) * 1e3, np.array(lower, dtype=float)


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
    a = ap.parse_args()
    creep = math.radians(a.pitch_creep_deg)
    pose = POSE if a.pose is None else (a.pose[0] * 1e-3, *map(math.radians, a.pose[1:]))
    t_est, t_all, lower = run(math.radians(a.phi_step_deg), a.prefetch, a.samples,
                              math.radians(a.theta_b_step_deg), creep, pose)
    skip = 5   # the first estimates load and compile
    for name, t in (('estimate', t_est[skip:]), ('estimate + prefetch', t_all[skip:])):
        q = np.percentile(t, [50, 90, 99])
        print(f'{name}: median {q[0]:.2f} ms, 90 % {q[1]:.1f} ms, 99 % {q[2]:.1f} ms, '
              f'max {t.max():.1f} ms; {int(np.sum(t > SLOW_MS))} of {len(t)} over '
              f'{SLOW_MS:g} ms; {t.sum() * 1e-3:.1f} s of computing in a '
              f'{len(t) * 1e-2:.1f} s tug')
    if a.compare_exact:
        exact = run(0.0, False, a.samples, 0.0, creep, pose)[2]
        d = lower - exact
        print(f'grid - exact lower bound: min {d.min():+.4f} N, max {d.max():+.4f} N '
              f'({int(np.sum(d > 0))} of {len(d)} samples above the exact bound)')


if __name__ == '__main__':
    main()
