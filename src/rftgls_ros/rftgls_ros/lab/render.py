"""Synthetic camera images of ArUco markers at known poses (for tests and sample bags).

Method (docs/design/minirquad-hardware.md): a pinhole camera without distortion; each marker
image from cv2.aruco.generateImageMarker, padded with a one-cell white quiet zone, is warped by the
exact
plane-to-image homography at `supersample` x resolution, alpha-blended on a grey background and
reduced with INTER_AREA; optional Gaussian blur and noise. Only the marker's bounding box is
rendered at the high resolution, which keeps a 1280x720 frame at a few ms per marker.

Pixel convention: OpenCV's, pixel centres at integers, so an image spans [-0.5, W - 0.5]. The
supersampled camera's principal point is (c + 0.5) s - 0.5 so both grids cover the same area.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from .bag_layout import CameraCalibration, MarkerSetup

CELL_PX = 32          # marker-image pixels per marker cell (sharp edges after the warp)


@dataclass(frozen=True)
class MarkerView:
    """One marker to draw: dictionary id, black-square side length L (m), and its pose in
    the camera frame (T_cam_marker, 4x4: marker x right, y up on the print, z out of it)."""

    marker_id: int
    length_m: float
    T_cam_marker: np.ndarray


# The ArUco API the lab tools use (OpenCV >= 4.7: the detector object and generateImageMarker).
ARUCO_API = ('ArucoDetector', 'DetectorParameters', 'generateImageMarker',
             'getPredefinedDictionary')


class ArucoUnavailable(ValueError):
    """This OpenCV has no (new enough) ArUco module (one line, says what to install)."""


def require_aruco() -> None:
    """ArucoUnavailable when cv2.aruco lacks the API above: Ubuntu 24.04's python3-opencv
    (4.6) has the older function API only."""
    aruco = getattr(cv2, 'aruco', None)
    missing = [n for n in ARUCO_API if not hasattr(aruco, n)]
    if missing:
        has = 'no aruco module' if aruco is None else 'an older ArUco API'
        raise ArucoUnavailable(
            f'ArUco tracking needs OpenCV >= 4.7 with cv2.aruco.{missing[0]}; this OpenCV '
            f'{getattr(cv2, "__version__", "?")} has {has} (install opencv-python-headless '
            '>= 4.7 in the venv, see the README\'s robot section)')


def aruco_dictionary(name: str):
    require_aruco()
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


@lru_cache(maxsize=32)
def _marker_image(dictionary: str, marker_id: int) -> tuple[np.ndarray, float]:
    """Padded marker image (uint8) and the ratio (padded side / black square side)."""
    d = aruco_dictionary(dictionary)
    cells = d.markerSize + 2                     # data cells + one black border cell each side
    img = cv2.aruco.generateImageMarker(d, marker_id, cells * CELL_PX, borderBits=1)
    padded = cv2.copyMakeBorder(img, CELL_PX, CELL_PX, CELL_PX, CELL_PX, cv2.BORDER_CONSTANT,
                                value=255)
    return padded, (cells + 2) / cells


def object_corners(length_m: float) -> np.ndarray:
    """Marker corners in its frame, ArUco order: top-left, top-right, bottom-right, bottom-left."""
    h = 0.5 * length_m
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def project(cam: CameraCalibration, T_cam_marker: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Pinhole projection (no distortion) of marker-frame points, px."""
    P = pts @ T_cam_marker[:3, :3].T + T_cam_marker[:3, 3]
    uvw = P @ cam.K_array.T
    return uvw[:, :2] / uvw[:, 2:3]


def render(cam: CameraCalibration, markers: list[MarkerView], dictionary: str = 'DICT_4X4_50',
           background: int = 190, blur_sigma_px: float = 0.0, noise_sigma: float = 0.0,
           supersample: int = 4, rng: np.random.Generator | None = None) -> np.ndarray:
    """A mono8 image (height x width) of the markers seen by the camera."""
    s = int(supersample)
    W, H = cam.width, cam.height
    img = np.full((H, W), float(background), np.float32)
    Ks = cam.K_array.copy()
    Ks[0, 0] *= s
    Ks[1, 1] *= s
    Ks[0, 1] *= s
    Ks[0, 2] = (Ks[0, 2] + 0.5) * s - 0.5
    Ks[1, 2] = (Ks[1, 2] + 0.5) * s - 0.5
    for mv in markers:
        tex, ratio = _marker_image(dictionary, mv.marker_id)
        n = tex.shape[0]
        Lp = mv.length_m * ratio                  # padded side, m
        # marker-image pixel (u, v) -> marker plane (X, Y): edges -0.5 and n - 0.5 map to -+Lp/2
        A = np.array([[Lp / n, 0.0, -Lp / 2 + 0.5 * Lp / n],
                      [0.0, -Lp / n, Lp / 2 - 0.5 * Lp / n],
                      [0.0, 0.0, 1.0]])
        T = mv.T_cam_marker
        Hs = Ks @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
        # bounding box in the full-resolution image, whole pixels, clipped to the frame
        edge = np.array([[-0.5, -0.5], [n - 0.5, -0.5], [n - 0.5, n - 0.5], [-0.5, n - 0.5]])
        q = cv2.perspectiveTransform(edge[None], Hs)[0]
        q = (q + 0.5) / s - 0.5
        x0, y0 = np.maximum(np.floor(q.min(0)).astype(int) - 2, 0)
        x1, y1 = np.minimum(np.ceil(q.max(0)).astype(int) + 3, [W, H])
        if x1 <= x0 or y1 <= y0:
            continue
        # shift the supersampled homography to the box's origin
        Sh = np.array([[1.0, 0.0, -x0 * s], [0.0, 1.0, -y0 * s], [0.0, 0.0, 1.0]])
        size = ((x1 - x0) * s, (y1 - y0) * s)
        warped = cv2.warpPerspective(tex.astype(np.float32), Sh @ Hs, size,
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                     borderValue=0)
        alpha = cv2.warpPerspective(np.ones_like(tex, np.float32), Sh @ Hs, size,
                                    flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                    borderValue=0)
        box = (slice(y0, y1), slice(x0, x1))
        small = cv2.resize(warped, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
        a = cv2.resize(alpha, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
        img[box] = img[box] * (1.0 - a) + small * a
    if blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma_px)
    if noise_sigma > 0:
        rng = rng or np.random.default_rng()
        img = img + rng.normal(0.0, noise_sigma, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def side_camera_pose(distance_m: float,
                     look_at_world: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """T_world3_cam of a camera on the -y side of the sagittal plane looking along +y at
    world point (x, 0, z), image right = world +x, image up = world +z. 3D world here: x, y, z."""
    T = np.eye(4)
    # camera axes in world: x_c = +x, y_c = -z (image down), z_c = +y (looking into the plane)
    T[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    T[:3, 3] = [look_at_world[0], -distance_m, look_at_world[1]]
    return T


def marker_in_world3(x: float, z: float, theta: float, y: float = 0.0) -> np.ndarray:
    """T_world3_marker of a marker facing a -y side camera: marker x at elevation theta from
    world x, marker y = world z rotated likewise, marker z = world -y; centre at (x, y, z)."""
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[:3, 0] = [c, 0.0, s]
    T[:3, 1] = [-s, 0.0, c]
    T[:3, 2] = [0.0, -1.0, 0.0]
    T[:3, 3] = [x, y, z]
    return T


@dataclass(frozen=True)
class BenchScene:
    """The lab bench seen by a side camera: the camera, the markers and where they are.

    camera_distance_m: from the camera centre to the sagittal plane (world y = 0);
    look_at: world (x, z) on the optical axis; robot_marker_y_m: out-of-plane offset of the
    robot marker (its print sits on the body's side, nearer the camera).
    """

    camera: CameraCalibration
    markers: MarkerSetup
    camera_distance_m: float = 0.40
    look_at: tuple[float, float] = (0.03, 0.04)
    robot_marker_y_m: float = 0.0

    def T_world_cam(self) -> np.ndarray:
        return side_camera_pose(self.camera_distance_m, self.look_at)

    def views(self, p_pose: np.ndarray) -> list[MarkerView]:
        """Both markers in the camera frame for p at planar pose (x_m, z_m, thetaB_rad)."""
        from . import planar
        m = self.markers
        robot = planar.compose(np.asarray(p_pose, float), planar.inverse(np.asarray(m.p_in_robot)))
        cam_inv = np.linalg.inv(self.T_world_cam())
        tank3 = marker_in_world3(*m.tank_in_world)
        robot3 = marker_in_world3(*robot, y=self.robot_marker_y_m)
        return [MarkerView(m.tank_id, m.tank_length_m, cam_inv @ tank3),
                MarkerView(m.robot_id, m.robot_length_m, cam_inv @ robot3)]


def default_bench() -> BenchScene:
    """The bench the tests and sample bags use (and a sensible real one): 1280x720 at
    f = 1400 px from 0.40 m (0.29 mm per px), a 60 mm tank marker on the tank wall 75 mm above
    the sand, a 50 mm robot marker 60 mm along the body from p and 30 mm above it."""
    return BenchScene(
        camera=CameraCalibration.simple(1280, 720, 1400.0),
        markers=MarkerSetup(dictionary='DICT_4X4_50', tank_id=0, tank_length_m=0.060,
                            robot_id=7, robot_length_m=0.050,
                            tank_in_world=(0.13, 0.075, 0.0), p_in_robot=(-0.06, -0.03, 0.0)))
