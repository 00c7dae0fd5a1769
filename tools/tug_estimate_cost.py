"""What one capacity estimate costs during a tug, and how far the lower bound's phi grid moves it.

    python tools/tug_estimate_cost.py --phi-step-deg 0.5 --prefetch
    python tools/tug_estimate_cost.py --phi-step-deg 0          # the bound at the exact phi

Feeds capacity_node's estimator (the shipped ros2_ws/params/capacity_node.yaml, map and live
edge checks included) the sequence a 600 g tug of `make demo` gives it: the planned gait's
pose held still (h 42.7 mm modelled with a 2.9 mm band, theta_B 10.4 deg, legs -20 deg) while
the tether angle creeps from -3.1 deg by 0.01 deg per tension sample. Prints the estimate's
time (and with its prefetch) as percentiles, and with --compare-exact how far the grid bound
lies from the exact-phi bound at every sample. No ROS.
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
from rftgls_ros.capacity.node_predictor import node_predictor
from rftgls_ros.capacity.params import DEFAULTS, configs

ROOT = Path(__file__).resolve().parents[1]
POSE = (0.0427358, 0.181783, -0.349066, -0.349066)   # h m, theta_B, theta_L1, theta_L2 rad
H_BAND_M = 0.0029
PHI0, DPHI = -0.054, 1.7e-4                           # rad, rad per tension sample


def run(step_rad: float, prefetch: bool, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(estimate ms, estimate + prefetch ms, lower bound N) per sample."""
    shipped = yaml.safe_load((ROOT / 'ros2_ws/params/capacity_node.yaml').read_text())
    p = {**DEFAULTS, **shipped['/**/capacity_node']['ros__parameters'],
         'lower_bound_phi_step_rad': step_rad}
    p['map_file'] = str(ROOT / p['map_file'])
    est_cfg, _ = configs(p)
    pred = node_predictor(p['map_file'], p['live_method'], p['robot'], p['medium'],
                          p['live_n_twists'], p['pull'], p['out_of_range_live_method'],
                          edge_live_method=p['edge_live_method'])
    e = CapacityEstimator(pred, est_cfg)
    h, pitch, l1, l2 = POSE
    t_est, t_all, lower = [], [], []
    for k in range(n):
        t = 0.01 * k
        e.update_joints(t, dict(zip(JOINTS, (l1, l1, l2, l2))))
        e.update('pitch', t, pitch)
        e.update('height', t, h, Provenance.MODELLED, H_BAND_M)
        e.update('phi', t, PHI0 - DPHI * k)
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
    ap.add_argument('--prefetch', action='store_true')
    ap.add_argument('--samples', type=int, default=400)
    ap.add_argument('--compare-exact', action='store_true',
                    help='also run the exact-phi bound and report grid - exact, N')
    a = ap.parse_args()
    t_est, t_all, lower = run(math.radians(a.phi_step_deg), a.prefetch, a.samples)
    skip = 5   # the first estimates load and compile
    for name, t in (('estimate', t_est[skip:]), ('estimate + prefetch', t_all[skip:])):
        q = np.percentile(t, [50, 90, 99])
        print(f'{name}: median {q[0]:.2f} ms, 90 % {q[1]:.1f} ms, 99 % {q[2]:.1f} ms, '
              f'max {t.max():.1f} ms')
    if a.compare_exact:
        exact = run(0.0, False, a.samples)[2]
        d = lower - exact
        print(f'grid - exact lower bound: min {d.min():+.4f} N, max {d.max():+.4f} N '
              f'({int(np.sum(d > 0))} of {len(d)} samples above the exact bound)')


if __name__ == '__main__':
    main()
