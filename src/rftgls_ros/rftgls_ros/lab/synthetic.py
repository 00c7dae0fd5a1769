"""Synthetic pull-test bags made by the simulated robot (clearly labelled synthetic).

A test: the arm takes up the slack (tension ramps from 0 to the breakaway capacity in
`hold_s`, nothing moves), then p slips along the quasi-static trajectory of the 'truth' model
(rftgls_core.sim, twist-mesh by default) at the pull speed while the load cell reads the
capacity along the way. Sensor noise: load cell, tracking (x, z, thetaB), leg encoders. The
metadata carries synthetic = true, the generating command and the truth medium.

    python -m rftgls_ros.lab.synthetic --out-dir DIR [--xi-n 4.2e5 --mu-surf 0.3] \
        [--config=-40,0,forward --config=-20,20,backward ...] [--h 0.02] [--seed 1]
        [--anchor FILE.yaml]

`--anchor` simulates an anchor description instead of the `--robot` preset (its state
variables fed from (h, thetaB, thetaL1, thetaL2) by name, predict.load_anchor); the bags
record the description's name as their robot and its identity in the notes.
"""
from __future__ import annotations

import math
import shlex
import sys
from dataclasses import dataclass

import numpy as np

from rftgls_conventions.safe_write import output_folder
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.predictor import Predictor
from rftgls_core.quantities import (
    ANGLE_DEG,
    MU_SURF,
    POSITION_M,
    SEED,
    SLIP_STEP_M,
    SLIP_TRAVEL_M,
    TETHER_PHI_DEG,
    XI_N,
)
from rftgls_core.rft.media import Medium, custom_medium, get_medium
from rftgls_core.types import AnchorState
from rftgls_node_base.node_main import program_args

from .bag_layout import PullTest, PullTestMeta, write_pull_test
from .predict import add_anchor_arguments, load_anchor, make_predictor, surface_min_z
from .render import default_bench

# (thetaL1 deg, thetaL2 deg, pull): leg pairs whose slip runs long enough to measure a slope
DEFAULT_CONFIGS = (( -40, 0, 'forward'), (-40, 20, 'backward'), (-40, 40, 'backward'),
                   (-20, 0, 'backward'), (-20, 20, 'backward'), (0, 40, 'backward'),
                   (-40, 20, 'forward'), (-20, 0, 'forward'))
T0_NS = 1_767_225_600_000_000_000      # 2026-01-01T00:00:00Z, a fixed epoch: bags reproduce


@dataclass(frozen=True)
class SensorModel:
    """Rates (Hz) and 1-sigma noise (SI) of the bench."""

    load_cell_hz: float = 50.0
    camera_hz: float = 15.0
    joints_hz: float = 10.0
    tension_sigma_N: float = 0.02
    xz_sigma_m: float = 0.15e-3          # tracking noise measured on the rendered bench
    theta_sigma_rad: float = math.radians(0.05)
    leg_sigma_rad: float = math.radians(0.2)


def synthesize(state: AnchorState, pull: str, truth: Medium, nominal: Medium,
               robot: str = 'prototype', phi: float = 0.0, test_id: str = 'synthetic',
               generator: str = '', speed: float = 2e-3, hold_s: float = 1.0,
               step: float = 1e-3, max_travel: float = 0.04, integrator: str = 'heun',
               method: str = 'twist-mesh', sensors: SensorModel = SensorModel(),
               seed: int = 0, predictor: Predictor | None = None,
               anchor=None) -> PullTest:
    """One synthetic pull test (SI). speed: pull speed of p along its path, m/s. anchor: an
    LabAnchor (predict.load_anchor) simulated instead of the preset `robot` (recorded under
    its name)."""
    from rftgls_core.sim.trajectory import simulate_pull

    rng = np.random.default_rng(seed)
    predictor = predictor or make_predictor(method, robot, truth, anchor=anchor)
    traj = simulate_pull(predictor, state, phi, pull, surface_min_z(robot, pull, anchor),
                         step=step, integrator=integrator, max_travel=max_travel).as_array()
    ok = np.isfinite(traj[:, 4])
    traj = traj[ok] if ok.any() else traj[:1]
    s_end = traj[-1, 0]
    f0 = traj[0, 4] if np.isfinite(traj[0, 4]) else 0.0
    t_end = hold_s + s_end / speed + 0.2

    def path_at(t: np.ndarray) -> np.ndarray:
        """(x, z, thetaB, force) at times t: hold, then the slip at `speed`."""
        s = np.clip((t - hold_s) * speed, 0.0, s_end)
        out = np.column_stack([np.interp(s, traj[:, 0], traj[:, k]) for k in (1, 2, 3, 4)])
        ramp = t < hold_s
        out[ramp, 3] = f0 * t[ramp] / hold_s
        return out

    ft = np.arange(0.0, t_end, 1.0 / sensors.load_cell_hz)
    force = path_at(ft)[:, 3] + rng.normal(0.0, sensors.tension_sigma_N, ft.size)
    pt = np.arange(0.0, t_end, 1.0 / sensors.camera_hz)
    pose = path_at(pt)[:, :3] + rng.normal(size=(pt.size, 3)) * [
        sensors.xz_sigma_m, sensors.xz_sigma_m, sensors.theta_sigma_rad]
    jt = np.arange(0.0, t_end, 1.0 / sensors.joints_hz)
    legs = np.array([state.theta_l1, state.theta_l2]) + rng.normal(
        0.0, sensors.leg_sigma_rad, (jt.size, 2))
    bench = default_bench()
    meta = PullTestMeta(
        test_id=test_id, robot=anchor.name if anchor is not None else robot,
        medium=nominal.to_dict(), pull=pull,
        initial_state=state, phi_rad=phi, synthetic=True, generator=generator,
        markers=bench.markers, camera=bench.camera, truth_medium=truth.to_dict(),
        notes=f'SYNTHETIC: simulated by rftgls_core ({method}, {integrator}, {step * 1e3:g} mm '
              f'steps; stop: {s_end * 1e3:.1f} mm), pull {speed * 1e3:g} mm/s, noise '
              f'{sensors.tension_sigma_N} N, {sensors.xz_sigma_m * 1e3} mm, '
              f'{math.degrees(sensors.theta_sigma_rad)} deg; seed {seed}'
              + (f'; anchor description {anchor.name} ({anchor.sha256[:12]})'
                 if anchor is not None else ''))
    return PullTest(meta=meta, t0_ns=T0_NS, force_t=ft, tension_N=np.maximum(force, 0.0),
                    phi_rad=np.full(ft.size, phi), pose_t=pt, pose=pose, joint_t=jt, legs=legs)


def parse_config(text: str) -> tuple[float, float, str]:
    l1, l2, pull = text.split(',')
    if pull not in ('forward', 'backward'):
        raise ValueError(f'pull must be forward or backward, got {pull!r}')
    return ANGLE_DEG.check(float(l1), 'L1'), ANGLE_DEG.check(float(l2), 'L2'), pull


def config_id(l1: float, l2: float, pull: str) -> str:
    return f'{pull}_L1{l1:+04.0f}_L2{l2:+04.0f}'


@cli_contract('synthetic')
def main(argv: list[str] | None = None) -> int:
    ap = RftglsParser(prog='python -m rftgls_ros.lab.synthetic',
                                 description='synthetic pull-test bags (labelled synthetic)')
    ap.add_argument('--out-dir', required=True)
    ap.add_argument('--robot', default='prototype')
    ap.add_argument('--nominal-medium', default='glass_beads',
                    help='medium recorded as the test medium (what the lab believes)')
    ap.add_argument('--xi-n', type=XI_N.arg, default=4.2e5, help='truth xi_n, N/m^3')
    ap.add_argument('--mu-surf', type=MU_SURF.arg, default=0.3, help='truth mu_surf')
    ap.add_argument('--config', action='append', type=parse_config,
                    help='L1_DEG,L2_DEG,PULL (repeat); default: 8 paper-like pairs')
    ap.add_argument('--h', type=POSITION_M.arg, default=0.02, help='initial h, m')
    ap.add_argument('--theta-b', type=ANGLE_DEG.arg, default=0.0, help='initial thetaB, deg')
    ap.add_argument('--phi', type=TETHER_PHI_DEG.arg, default=0.0, help='tether angle, deg')
    ap.add_argument('--method', default='twist-mesh')
    ap.add_argument('--step', type=SLIP_STEP_M.arg, default=1e-3,
                    help='m of p per simulation step')
    ap.add_argument('--max-travel', type=SLIP_TRAVEL_M.arg, default=0.04, help='m')
    ap.add_argument('--integrator', choices=['euler', 'heun'], default='heun')
    ap.add_argument('--seed', type=SEED, default=1)
    ap.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap')
    add_anchor_arguments(ap)
    args = ap.parse_args(program_args(argv, ap.prog))
    try:
        out = output_folder(args.out_dir, '--out-dir')   # checked before any work
        anchor = load_anchor(args.anchor, args.anchor_state)
    except ValueError as exc:
        print(f'synthetic: error: {exc}', file=sys.stderr)
        return 2
    generator = 'python -m rftgls_ros.lab.synthetic ' + shlex.join(
        sys.argv[1:] if argv is None else argv)
    truth = custom_medium(xi_n=args.xi_n, mu_surf=args.mu_surf)
    truth = Medium('synthetic_truth', truth.xi_n, truth.mu_surf, truth.zeta,
                   note='truth of synthetic bags')
    nominal = get_medium(args.nominal_medium)
    predictor = make_predictor(args.method, args.robot, truth, anchor=anchor)
    from tqdm import tqdm
    configs = args.config or DEFAULT_CONFIGS
    for k, (l1, l2, pull) in enumerate(tqdm(configs, unit='test', file=sys.stderr)):
        tid = config_id(l1, l2, pull)
        state = AnchorState.from_degrees(args.h, args.theta_b, l1, l2)
        test = synthesize(state, pull, truth, nominal, robot=args.robot,
                          phi=math.radians(args.phi), test_id=tid, generator=generator,
                          step=args.step, max_travel=args.max_travel,
                          integrator=args.integrator, method=args.method,
                          seed=args.seed * 1000 + k, predictor=predictor, anchor=anchor)
        path = out / tid
        if path.is_dir() and not path.is_symlink():   # a bag of an earlier run: replaced
            import shutil
            shutil.rmtree(path)
        write_pull_test(path, test, storage=args.storage)
        print(f'{path}: peak {test.tension_N.max():.2f} N, {test.pose_t[-1]:.1f} s')
    return 0


if __name__ == '__main__':
    sys.exit(main())
