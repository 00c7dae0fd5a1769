"""Is a slipping anchor visible to the stack? One closed-loop cycle without ROS.

    python tools/slip_visibility.py --sled 0.4 --sand-scale 0.5 --burrow-modes planned
    python tools/slip_visibility.py --sled 0.4 --sand-scale 0.5 --burrow-modes table_ii

behavior's machine (BehaviorMachine, the shipped map as capacity_node answers it) drives the
simulator's robot model (tests/stack/plant.py: the scripted body, the winch and sled, the live
ground on true sand x --sand-scale). Prints the mode burrowed, how the cycle was recorded,
the slip the stack detected (if any), how far the anchor really slipped under the tug, its
pitch change over the tug and the tension it slid at: what the robot's sensors saw of it.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'tests' / 'stack'))

from plant import Plant, fast_config, run_loop  # noqa: E402

from minirquad_sim.gait_pose import GaitPoses  # noqa: E402
from minirquad_sim.ground import LiveGround  # noqa: E402
from rftgls_ros.behavior import BehaviorMachine, ModeChooser, State  # noqa: E402
from rftgls_ros.behavior.planned import GaitChooser, sled_map  # noqa: E402
from rftgls_ros.capacity.node_predictor import DEFAULT_MAP, node_predictor  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--sled', type=float, default=0.4, help='sled mass, kg')
    ap.add_argument('--sand-scale', type=float, default=0.5,
                    help="true sand strength / the stack's (0 < x <= 2)")
    ap.add_argument('--burrow-modes', choices=('planned', 'table_ii'), default='planned')
    a = ap.parse_args(argv)
    if not (0.0 < a.sand_scale <= 2.0 and 0.0 < a.sled <= 5.0):
        ap.error('need 0 < --sand-scale <= 2 and 0 < --sled <= 5')
    pred = node_predictor(DEFAULT_MAP, robot=None, medium=None, edge_live_method='direct-warm')
    cfg = fast_config(sled_mass_kg=a.sled, cycles=1, burrow_modes=a.burrow_modes,
                      walk_time_s=2.5).check()
    chooser = (GaitChooser(pred, sled_map('minirquad', a.sled), 1.0, cfg.phis_rad,
                           cfg.plan_confidence) if a.burrow_modes == 'planned'
               else ModeChooser(pred, cfg.safety_factor, cfg.phis_rad))
    m = BehaviorMachine(cfg, chooser)
    plant = Plant(a.sled, pred, ground=LiveGround(medium_scale=a.sand_scale),
                  gait_poses=GaitPoses.for_sled(a.sled))
    seen: dict = {}

    def watch(p, mach):
        if mach.state == State.TUG:
            seen.setdefault('pitch0', p.robot.theta_b)
            seen['pitch1'] = p.robot.theta_b
            if mach.obs.tension is not None and p.tug_slip > 0.005:
                seen.setdefault('slide_tension', mach.obs.tension)
    run_loop(m, plant, t_max=120, on_step=watch)
    r = m.records[0] if m.records else None
    pitch = math.degrees(seen.get('pitch1', math.nan) - seen.get('pitch0', math.nan))
    print(json.dumps({
        'mode': r.mode if r else None, 'outcome': r.outcome if r else None,
        'reason': r.reason if r else None, 'slip_detected': (r.slip or None) if r else None,
        'anchor_slip_under_tug_m': round(plant.tug_slip, 4),
        'pitch_change_over_tug_deg': round(pitch, 3),
        'tension_while_sliding_N': seen.get('slide_tension'),
        'need_N': round(m.need.value, 3)}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
