"""`rftgls figure fig8|fig9|fig10b`: the paper's views recomputed from our model."""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from rftgls_conventions.safe_write import write_text

from ..charts.figure_io import figure_path
from ..predictor.live import RobotPredictor
from ..quantities import ANGLE_DEG, FRICTION_SIGMA, RELATIVE_SIGMA, SLED_FRICTION
from ..rft.media import ASSUMED_MU_SIGMA, ASSUMED_XI_REL_SIGMA, get_medium
from ..robots.presets import get_robot
from ..robots.robot import G
from ..types import AnchorState, Pull


def add_parser(sub) -> None:
    p = sub.add_parser('figure', help="the paper's figures from our model (fig8, fig9, fig10b, "
                                      "fig13)")
    p.add_argument('which', choices=['fig8', 'fig9', 'fig10b', 'fig13'])
    p.add_argument('--out', required=True, help='PNG file (numbers go next to it as .json)')
    p.add_argument('--method', default='twist-mesh',
                   help='limit-surface method for fig9/fig10b (default twist-mesh: it keeps a '
                        'conservative value where the RFT map jumps and direct has no root)')
    p.add_argument('--sled-friction', type=SLED_FRICTION.arg, default=0.5,
                   help='fig10b: sled force = mu * m * g (assumed mu, default 0.5)')
    p.add_argument('--medium', default=None,
                   help='fig10b: medium preset or a `rftgls calibrate` JSON; its covariance '
                        'gives the uncertainty band')
    p.add_argument('--xi-rel-sigma', type=RELATIVE_SIGMA.arg, default=ASSUMED_XI_REL_SIGMA,
                   help='fig10b without a calibration: relative 1-sigma of xi_n (assumed 10 %%)')
    p.add_argument('--mu-sigma', type=FRICTION_SIGMA.arg, default=ASSUMED_MU_SIGMA,
                   help='fig10b without a calibration: 1-sigma of mu_surf (assumed 0.1)')
    p.add_argument('--l1', type=ANGLE_DEG.arg, default=-40.0, help='fig8: thetaL1, deg')
    p.add_argument('--l2', type=ANGLE_DEG.arg, default=0.0, help='fig8: thetaL2, deg')
    p.set_defaults(run=run)


def run(args) -> int:
    from tqdm import tqdm

    from ..charts import paper_figures as pf
    out = figure_path(args.out)      # checked before any work: a figure file, not a folder
    if args.which == 'fig13':
        return _fig13(args, out)
    if args.which == 'fig9':
        predictor = RobotPredictor(get_robot('prototype'), get_medium('glass_beads'),
                                   method=args.method)
        bar = tqdm(total=50, desc='fig9 poses', file=sys.stderr)
        maps = pf.leg_angle_maps(predictor, progress=bar.update)
        bar.close()
        pf.plot_leg_angle_maps(maps, out, f'prototype in glass beads, h = 20 mm, thetaB = 0, '
                                          f'phi = 0, method {args.method}')
        data = {pull: {k: v.tolist() for k, v in g.items()} for pull, g in maps.items()}
    elif args.which == 'fig8':
        from ..charts.trajectory import plot_trajectories
        robot, medium = get_robot('prototype'), get_medium('glass_beads')
        state = AnchorState.from_degrees(0.02, 0.0, args.l1, args.l2)
        data = {}
        for pull in Pull:
            runs = {}
            for method in ('direct', 'twist-mesh', 'alpha', 'ellipsoid'):
                predictor = RobotPredictor(robot, medium, method=method)
                summary, traj = pf.slip_summary(predictor, state, pull, travel=0.04, step=0.001)
                runs[method] = traj
                data[f'{pull.value}/{method}'] = summary.__dict__
            plot_trajectories(runs, out.with_name(f'{out.stem}_{pull.value}{out.suffix}'),
                              title=f'prototype, ({args.l1:.0f}, {args.l2:.0f}) deg, '
                                    f'{pull.value} pull, phi = 0')
    else:
        import numpy as np

        from ..rft.media import load_medium
        from ..uncertainty import capacity_band
        from .demo import ANCHOR_MODES
        medium = load_medium(args.medium or 'm90_sand')
        cov = _medium_covariance(args)
        predictor = RobotPredictor(get_robot('minirquad'), medium, method=args.method)
        caps: dict[str, dict] = {}
        lows: dict[str, dict] = {}
        for mode, state in ANCHOR_MODES.items():
            caps[mode], lows[mode] = {}, {}
            for phi in (0.0, -20.0):
                band = capacity_band('minirquad', medium.xi_n, medium.mu_surf, cov, state,
                                     math.radians(phi), 'backward', method=args.method)
                res = predictor.predict(state, math.radians(phi), Pull.BACKWARD)
                caps[mode][phi] = res.capacity_N
                lows[mode][phi] = band.lower_N if res.capacity_N is not None else None
        needs = {f'{int(m * 1e3)} g': args.sled_friction * m * G for m in (0.4, 0.6)}
        pf.plot_anchor_modes(caps, needs, out, f'MiniRQuad anchors in {medium.name} (backward '
                                               f'pull), sled mu = {args.sled_friction}',
                             lower=lows)
        data = {'capacity_N': {m: {str(k): v for k, v in c.items()} for m, c in caps.items()},
                'lower_95_N': {m: {str(k): v for k, v in c.items()} for m, c in lows.items()},
                'covariance_xi_mu': np.asarray(cov).tolist(), 'sled_force_N': needs}
    write_text(out.with_suffix('.json'), json.dumps(data, indent=2, default=float))
    print(f'wrote {out} (and .json)')
    return 0


def _fig13(args, out: Path) -> int:
    """The ellipsoid pull-out of the paper's Fig. 13 (assumptions in charts/fig13.py)."""
    from tqdm import tqdm

    from ..charts.fig13 import fig13_data, plot_fig13
    bar = tqdm(desc='fig13 steps', file=sys.stderr, leave=False)
    data, trajs = fig13_data(method=args.method, progress=lambda k: bar.update(1))
    bar.close()
    plot_fig13(data, trajs, out)
    write_text(out.with_suffix('.json'), json.dumps(data, indent=2))
    print(f'wrote {out} (and .json)')
    return 0


def _medium_covariance(args):
    """(xi_n, mu_surf) covariance: from a calibration file, else the assumed sigmas."""
    from ..rft.media import load_medium, medium_covariance
    xi = load_medium(args.medium or 'm90_sand').xi_n
    return medium_covariance(args.medium, xi, args.xi_rel_sigma, args.mu_sigma)[0]
