"""Tracking accuracy on rendered frames at known poses (the issue's 1 mm / 0.2 deg check).

    python -m rftgls_ros.lab.tracking_accuracy [--frames 200] [--noise 2] [--blur 0.6] [--seed 1]

Random poses of p cover a pull test: x in [-80, 0] mm (pulled toward -x), h in [0, 30] mm,
thetaB in [-10, 35] deg, on the default bench (render.default_bench). Errors are |est - true|
of x, z and thetaB of p in lab_world.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.quantities import IMAGE_BLUR_PX, IMAGE_NOISE, SEED, bounded_int
from rftgls_node_base.node_main import program_args

from .aruco_tracking import ArucoTracker, TrackerConfig
from .render import BenchScene, default_bench, render


@dataclass
class AccuracyResult:
    true: np.ndarray        # (F, 3)
    est: np.ndarray         # (F, 3), NaN where no pose
    reprojection_px: np.ndarray

    @property
    def err(self) -> np.ndarray:
        """(F, 3) absolute errors: x m, z m, thetaB rad."""
        return np.abs(self.est - self.true)

    def summary(self) -> dict:
        e = self.err
        found = np.isfinite(e).all(axis=1)
        out = {'frames': int(len(e)), 'tracked': int(found.sum())}
        for i, (name, scale, unit) in enumerate((('x', 1e3, 'mm'), ('z', 1e3, 'mm'),
                                                  ('theta_b', np.degrees(1.0), 'deg'))):
            v = e[found, i] * scale
            out[name] = {'median': float(np.median(v)), 'p95': float(np.percentile(v, 95)),
                         'max': float(v.max()), 'unit': unit}
        return out


def random_poses(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.uniform(-0.08, 0.0, n), rng.uniform(0.0, 0.03, n),
                            np.radians(rng.uniform(-10.0, 35.0, n))])


def measure(n: int = 100, noise: float = 2.0, blur: float = 0.6, seed: int = 1,
            scene: BenchScene | None = None, config: TrackerConfig | None = None,
            progress: bool = False) -> AccuracyResult:
    scene = scene or default_bench()
    config = config or TrackerConfig()
    rng = np.random.default_rng(seed)
    poses = random_poses(n, rng)
    tracker = ArucoTracker(scene.camera, scene.markers, config)
    frames = ((float(i), render(scene.camera, scene.views(p), scene.markers.dictionary,
                                blur_sigma_px=blur, noise_sigma=noise, rng=rng))
              for i, p in enumerate(poses))
    pose_t, pose, tracking = tracker.track(frames, progress=progress)
    est = np.full_like(poses, np.nan)
    est[pose_t.astype(int)] = pose
    return AccuracyResult(poses, est, tracking.reprojection_px)


@cli_contract('tracking_accuracy')
def main(argv: list[str] | None = None) -> int:
    ap = RftglsParser(prog='python -m rftgls_ros.lab.tracking_accuracy',
                      description=__doc__.split('\n\n')[0])
    ap.add_argument('--frames', type=bounded_int(1, 100_000, 'frame count'), default=200)
    ap.add_argument('--noise', type=IMAGE_NOISE.arg, default=2.0,
                    help='image noise sigma, grey levels')
    ap.add_argument('--blur', type=IMAGE_BLUR_PX.arg, default=0.6,
                    help='Gaussian blur sigma, px')
    ap.add_argument('--seed', type=SEED, default=1)
    args = ap.parse_args(program_args(argv, ap.prog))
    res = measure(args.frames, args.noise, args.blur, args.seed, progress=True)
    s = res.summary()
    print(f"{s['tracked']}/{s['frames']} frames tracked "
          f"(noise {args.noise} grey levels, blur {args.blur} px, seed {args.seed})")
    for k in ('x', 'z', 'theta_b'):
        v = s[k]
        print(f"  {k:8s} median {v['median']:.3f}  p95 {v['p95']:.3f}  max {v['max']:.3f} "
              f"{v['unit']}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
