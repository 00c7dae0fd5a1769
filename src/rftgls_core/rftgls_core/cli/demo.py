"""`rftgls demo`: the main job on shipped defaults, without ROS.

MiniRQuad in M90 sand: capacity of the paper's three burrowed anchors (Table II: DH, DL, SH)
for a horizontal and a -20 deg tether, against the force two sleds need, and the limit-surface
plot of the DH anchor. The `holds` column is the paper's point-estimate rule (the capacity at
the Table II mean against the need), reproduced offline; the robot (behavior_node,
`make demo`) decides on the lower bound over the burrow depth it does not measure, and never
on this column.
"""
from __future__ import annotations

import json
import math
import time

from rftgls_conventions.safe_write import output_folder, write_text

from ..charts.limit_surface import plot_limit_surface
from ..predictor.live import RobotPredictor
from ..rft.media import get_medium
from ..robots.presets import minirquad
from ..robots.robot import G
from ..types import AnchorState, Pull

# Paper Table II: final leg angles (deg) and the measured mean thetaB (deg) and h (mm).
ANCHOR_MODES = {
    'DH': AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0),
    'DL': AnchorState.from_degrees(0.036, 8.9, -40.0, 0.0),
    'SH': AnchorState.from_degrees(0.047, 2.4, -40.0, 30.0),
}
# Sled pull force = mu_sled * m * g; mu_sled = 0.5 is an assumed sand-on-plastic friction.
SLED_FRICTION = 0.5
SLEDS_KG = (0.4, 0.6)


def add_parser(sub) -> None:
    p = sub.add_parser('demo', help='capacity of the DH/DL/SH anchors of MiniRQuad + plots')
    p.add_argument('--out', default='out/demo', help='output folder (default %(default)s)')
    p.add_argument('--method', default='twist-mesh')
    p.set_defaults(run=run)


def run(args) -> int:
    out = output_folder(args.out, '--out')
    robot = minirquad()
    predictor = RobotPredictor(robot, get_medium('m90_sand'), method=args.method)
    needs = {m: SLED_FRICTION * m * G for m in SLEDS_KG}
    print(f'MiniRQuad ({robot.mass * 1e3:.0f} g) in M90 sand, backward pulls (winch on its '
          f'back), method {args.method}')
    print(f'sled force needed (mu_sled = {SLED_FRICTION:.2f}): '
          + ', '.join(f'{1e3 * m:.0f} g -> {f:.2f} N' for m, f in needs.items()))
    print(f'{"mode":<5}{"h [mm]":>8}{"thetaB":>8}{"L1":>6}{"L2":>6}'
          f'{"cap phi=0 [N]":>15}{"cap phi=-20 [N]":>17}  holds (paper\'s point-estimate rule, '
          f'not the robot\'s)')
    rows = []
    t0 = time.perf_counter()
    for name, state in ANCHOR_MODES.items():
        res = predictor.predict_many(state, [0.0, math.radians(-20.0)], Pull.BACKWARD)
        caps = [r.capacity_N for r in res]
        weakest = min((c for c in caps if c is not None), default=None)
        holds = [f'{1e3 * m:.0f} g' for m, f in needs.items()
                 if weakest is not None and all(r.status.has_value for r in res) and weakest >= f]
        deg = [math.degrees(a) for a in state.as_tuple()[1:]]
        fmt = lambda r: f'{r.capacity_N:.2f}' if r.capacity_N is not None else r.status.value
        print(f'{name:<5}{1e3 * state.h:>8.0f}{deg[0]:>8.1f}{deg[1]:>6.0f}{deg[2]:>6.0f}'
              f'{fmt(res[0]):>15}{fmt(res[1]):>17}  {", ".join(holds) or "none"}')
        rows.append({'mode': name, 'state_si': state.as_tuple(),
                     'capacity_N': {'phi_0': caps[0], 'phi_-20': caps[1]},
                     'status': [r.status.value for r in res], 'holds': holds})
    print(f'({1e3 * (time.perf_counter() - t0):.0f} ms for 3 anchors x 2 tether angles)')
    plot = out / 'limit_surface_DH.png'
    plot_limit_surface(predictor, ANCHOR_MODES['DH'], Pull.BACKWARD, 0.0, plot)
    write_text(out / 'anchors.json', json.dumps({'sled_force_N': {str(k): v for k, v in
                                                                   needs.items()},
                                                  'anchors': rows}, indent=2))
    print(f'wrote {plot} and {out / "anchors.json"}')
    return 0
