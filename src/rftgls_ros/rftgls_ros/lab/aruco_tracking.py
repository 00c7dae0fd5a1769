"""ArUco tracking: camera frames + calibration -> planar track (x, z, thetaB) of the winch point.

Per frame (OpenCV 5 API, docs/design/minirquad-hardware.md):
  1. ArucoDetector with SUBPIX corner refinement finds the tank and robot markers;
  2. solvePnPGeneric(SOLVEPNP_IPPE_SQUARE) gives both planar solutions per marker; the tank
     marker keeps the one with the smaller reprojection error, the robot marker the one whose
     normal agrees best with the tank's (both face the camera, nearly parallel), so IPPE flips
     of a small or far marker do not reach the track;
  3. T_rel = T_cam_tank^-1 T_cam_robot -> planar (x, z, theta) + out-of-plane residual (method A
     of 4.4), then p in lab_world = tank_in_world o T_rel o p_in_robot (planar.py).
A frame where either marker is missing yields no pose: the gap is reported (Tracking.ok,
/lab/tracking ERROR "lost"), never interpolated.

CLI:
    python -m rftgls_ros.lab.aruco_tracking (--images DIR | --video FILE) --camera cam.json \
        (--meta meta.json | --bag-in IN_BAG) --out OUT_BAG [--fps 30] [--storage mcap]
"""
from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from rftgls_conventions.safe_read import check_folder, check_regular, read_text
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.quantities import FRAME_RATE_HZ
from rftgls_node_base.node_main import program_args

from . import planar
from .bag_layout import (
    MARKERS,
    CameraCalibration,
    MarkerSetup,
    PullTest,
    PullTestMeta,
    Tracking,
    read_pull_test,
    write_pull_test,
)
from .render import aruco_dictionary, object_corners, require_aruco


@dataclass(frozen=True)
class TrackerConfig:
    """Detector settings. SUBPIX halves the corner error (4.3); the window must fit inside
    one marker cell of the smallest marker in the image."""

    corner_refinement: str = 'SUBPIX'
    refinement_win_px: int = 5
    refinement_max_iter: int = 50
    refinement_min_accuracy_px: float = 0.01


@dataclass(frozen=True)
class MarkerObservation:
    T_cam_marker: np.ndarray     # 4x4
    reprojection_px: float       # RMS over the four corners
    corners_px: np.ndarray       # (4, 2), detector order


def _rt_to_T(rvec, tvec) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, float).reshape(3))[0]
    T[:3, 3] = np.asarray(tvec, float).reshape(3)
    return T


class ArucoTracker:
    """Stateless per frame; one instance per camera and marker setup."""

    def __init__(self, camera: CameraCalibration, markers: MarkerSetup,
                 config: TrackerConfig = TrackerConfig()):
        self.camera = camera
        self.markers = markers
        require_aruco()           # one clear line on an OpenCV without the detector API
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = getattr(cv2.aruco,
                                                f'CORNER_REFINE_{config.corner_refinement}')
        params.cornerRefinementWinSize = config.refinement_win_px
        params.cornerRefinementMaxIterations = config.refinement_max_iter
        params.cornerRefinementMinAccuracy = config.refinement_min_accuracy_px
        self.detector = cv2.aruco.ArucoDetector(aruco_dictionary(markers.dictionary), params)
        self.K, self.dist = camera.K_array, camera.dist_array
        self.ids = {'tank': markers.tank_id, 'robot': markers.robot_id}
        self.lengths = {'tank': markers.tank_length_m, 'robot': markers.robot_length_m}

    def detect(self, gray: np.ndarray) -> dict[str, MarkerObservation]:
        """Observations of the tank and robot markers found in one mono8 frame."""
        corners, ids, _ = self.detector.detectMarkers(gray)
        out: dict[str, MarkerObservation] = {}
        if ids is None or len(ids) == 0:
            return out
        ids = np.asarray(ids).reshape(-1)        # (N,) in OpenCV 5, (N, 1) in 4.x
        ref_normal = None
        for name in MARKERS:                     # tank first: the robot's choice uses its normal
            hits = np.flatnonzero(ids == self.ids[name])
            if hits.size != 1:                   # missing, or ambiguous duplicates: not measured
                continue
            img = np.asarray(corners[hits[0]], float).reshape(4, 2)
            obj = object_corners(self.lengths[name])
            n, rvecs, tvecs, errs = cv2.solvePnPGeneric(obj, img, self.K, self.dist,
                                                        flags=cv2.SOLVEPNP_IPPE_SQUARE)
            if n == 0:
                continue
            Ts = [_rt_to_T(r, t) for r, t in zip(rvecs, tvecs)]
            errs = np.asarray(errs, float).reshape(-1)
            if name == 'robot' and ref_normal is not None:
                k = int(np.argmax([T[:3, 2] @ ref_normal for T in Ts]))
            else:
                k = int(np.argmin(errs))
            if name == 'tank':
                ref_normal = Ts[k][:3, 2]
            out[name] = MarkerObservation(Ts[k], float(errs[k]), img)
        return out

    def planar_pose(self, obs: dict[str, MarkerObservation]) -> tuple[np.ndarray | None, float]:
        """p in lab_world (x_m, z_m, thetaB_rad) and the out-of-plane offset (m), or None."""
        if 'tank' not in obs or 'robot' not in obs:
            return None, math.nan
        T_rel = np.linalg.inv(obs['tank'].T_cam_marker) @ obs['robot'].T_cam_marker
        rel, oop = planar.from_marker_transform(T_rel)
        p = planar.compose(np.asarray(self.markers.tank_in_world),
                           planar.compose(rel, np.asarray(self.markers.p_in_robot)))
        return p, float(oop)

    def track(self, frames: Iterable[tuple[float, np.ndarray]],
              progress: bool = False) -> tuple[np.ndarray, np.ndarray, Tracking]:
        """Frames (t_s, image) -> (pose_t (M,), pose (M, 3), Tracking of all F frames)."""
        ts, ok, rep, oop, poses = [], [], [], [], {m: [] for m in MARKERS}
        pose_t, pose = [], []
        it = frames
        if progress:
            from tqdm import tqdm
            it = tqdm(frames, unit='frame', desc='aruco', file=sys.stderr)
        nan44 = np.full((4, 4), np.nan)
        for t, img in it:
            gray = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
            obs = self.detect(gray)
            p, off = self.planar_pose(obs)
            ts.append(t)
            ok.append([m in obs for m in MARKERS])
            rep.append([obs[m].reprojection_px if m in obs else np.nan for m in MARKERS])
            oop.append(off)
            for m in MARKERS:
                poses[m].append(obs[m].T_cam_marker if m in obs else nan44)
            if p is not None:
                pose_t.append(t)
                pose.append(p)
        tracking = Tracking(t=np.asarray(ts, float), ok=np.asarray(ok, bool).reshape(-1, 2),
                            reprojection_px=np.asarray(rep, float).reshape(-1, 2),
                            out_of_plane_m=np.asarray(oop, float),
                            marker_poses={m: np.asarray(v).reshape(-1, 4, 4)
                                          for m, v in poses.items()})
        return (np.asarray(pose_t, float), np.asarray(pose, float).reshape(-1, 3), tracking)


# -- frame sources ------------------------------------------------------------------------------
IMAGE_SUFFIXES = ('.png', '.jpg', '.jpeg', '.bmp', '.tif', '.tiff', '.pgm')


def image_folder_frames(folder: str | Path, fps: float) -> Iterator[tuple[float, np.ndarray]]:
    """Sorted image files. Times from `timestamps.csv` (file,t_s per line) when present, else
    index / fps. Use capture times: processing times would skew the track. The folder and
    every file are checked now (safe_read), the frames read as they are iterated."""
    folder = check_folder(folder, 'folder of frames')
    files = sorted(f for f in folder.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES)
    for f in files:     # every frame a regular file within the size limit, before any work
        check_regular(f, 'image', 'camera frame')
    stamps = {}
    csv = folder / 'timestamps.csv'
    if os.path.lexists(csv):
        for line in read_text(csv, 'csv', 'frame time stamps').splitlines():
            parts = line.strip().split(',')
            if len(parts) == 2 and parts[0] and not parts[0].startswith('#'):
                try:
                    stamps[parts[0]] = float(parts[1])
                except ValueError:
                    continue       # header line
    return _image_frames(files, stamps, fps)


def _image_frames(files: list[Path], stamps: dict[str, float], fps: float
                  ) -> Iterator[tuple[float, np.ndarray]]:
    for i, f in enumerate(files):
        img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f'cannot read image {f}')
        yield stamps.get(f.name, i / fps), img


def video_frames(path: str | Path) -> Iterator[tuple[float, np.ndarray]]:
    """Frames of a video file with the container's timestamps (s); the file is checked
    (safe_read) and opened now, the frames read as they are iterated."""
    cap = cv2.VideoCapture(str(check_regular(path, 'video', 'video')))
    if not cap.isOpened():
        raise ValueError(f'cannot open video {path}')
    return _video_frames(cap)


def _video_frames(cap) -> Iterator[tuple[float, np.ndarray]]:
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                return
            yield cap.get(cv2.CAP_PROP_POS_MSEC) * 1e-3, cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    finally:
        cap.release()


def track_into_bag(frames: Iterable[tuple[float, np.ndarray]], camera: CameraCalibration,
                   out: str | Path, base: PullTest | None = None,
                   meta: PullTestMeta | None = None, storage: str = 'mcap',
                   progress: bool = True) -> PullTest:
    """Track the frames and write a pull-test bag: the base bag's other topics (load cell,
    legs, metadata) with the pose and tracking replaced, or a new bag from meta alone.
    Frame times are seconds from the bag's t0."""
    if base is None and meta is None:
        raise ValueError('give a base bag or the test metadata')
    meta = replace(base.meta if base else meta, camera=camera)
    tracker = ArucoTracker(camera, meta.markers)
    pose_t, pose, tracking = tracker.track(frames, progress=progress)
    if base is None:
        empty = np.zeros(0)
        base = PullTest(meta=meta, t0_ns=0, force_t=empty, tension_N=empty, phi_rad=empty,
                        pose_t=empty, pose=np.zeros((0, 3)), joint_t=empty, legs=np.zeros((0, 2)))
    test = replace(base, meta=meta, pose_t=pose_t, pose=pose, tracking=tracking)
    write_pull_test(out, test, storage=storage)
    return test


@cli_contract('aruco_tracking')
def main(argv: list[str] | None = None) -> int:
    ap = RftglsParser(prog='python -m rftgls_ros.lab.aruco_tracking',
                                 description='ArUco frames -> planar track of p in a pull-test bag')
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument('--images', help='folder of frames (optional timestamps.csv: file,t_s)')
    src.add_argument('--video', help='video file')
    ap.add_argument('--fps', type=FRAME_RATE_HZ.arg, default=30.0,
                    help='image-folder rate without timestamps')
    ap.add_argument('--camera', required=True,
                    help='camera JSON {width, height, K: 3x3 px, dist: [k1 k2 p1 p2 k3]}')
    base = ap.add_mutually_exclusive_group(required=True)
    base.add_argument('--bag-in', help='pull-test bag whose pose/tracking is replaced')
    base.add_argument('--meta', help='PullTestMeta JSON for a new bag (see lab_README.md)')
    ap.add_argument('--out', required=True, help='output bag directory (must not exist)')
    ap.add_argument('--storage', choices=['mcap', 'sqlite3'], default='mcap')
    args = ap.parse_args(program_args(argv, ap.prog))
    try:
        if os.path.lexists(args.out) and not os.path.islink(args.out):
            raise ValueError(f'--out {args.out}: already exists; give a new bag folder')
        camera = CameraCalibration.load(args.camera)
        frames = (image_folder_frames(args.images, args.fps) if args.images
                  else video_frames(args.video))
        basetest = read_pull_test(args.bag_in) if args.bag_in else None
        meta = (PullTestMeta.from_json(read_text(args.meta, 'calibration', 'test metadata'),
                                       args.meta) if args.meta else None)
        test = track_into_bag(frames, camera, args.out, base=basetest, meta=meta,
                              storage=args.storage)
    except (ValueError, OSError, KeyError, json.JSONDecodeError) as exc:
        print(f'aruco_tracking: error: {exc}', file=sys.stderr)
        return 2
    tr = test.tracking
    lost = tr.lost_times()
    print(f'{len(tr.t)} frames, {len(test.pose_t)} poses of p; lost: tank {lost["tank"].size}, '
          f'robot {lost["robot"].size} frames; median reprojection '
          f'{np.nanmedian(tr.reprojection_px):.3f} px; wrote {args.out}')
    if lost['p'].size:
        print('frames without a pose (s): ' + ' '.join(f'{t:.3f}' for t in lost['p'][:50])
              + (' ...' if lost['p'].size > 50 else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
