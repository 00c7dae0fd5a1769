"""Marker geometry of one capacity estimate, without ROS (capacity_node only publishes it).

What is drawn (all in the tether plane, the sagittal x-z plane through the winch point p):
  limit_curve  the granular limit surface cut by My = 0 (a tether carries no moment at p): the
               points C(phi) d(phi) for tether angles phi the predictor answers with a value,
               forces drawn as lengths (force_scale_m_per_N);
  tension      the tether force T d(phi) at p;
  capacity     the capacity C d(phi) along the same direction, coloured by the margin
               (green: margin >= MARGIN_GREEN of the capacity, red: none or negative);
  slip_twist   the predicted slip direction (vx, vz) of p, twist_length_m long (red while
               slipping); its wy is in the text;
  buried_facets  centroids of the leg facets below the free surface (the ones RFT loads);
  surface      the free surface z = 0 (a line through the sagittal plane, h below p);
  text         status, capacity, tension and margin.

Frames: the numbers come in world-aligned axes at p (docs/design/architecture.md, "Frames and
signs": x horizontal toward the axles, z up). The markers are expressed in the body frame B at
p (x_B along the body toward the axles, z_B out of the plate; the URDF's winch_link): a world
vector v has body components (v_x cos thB + v_z sin thB, v_y, -v_x sin thB + v_z cos thB), with
thB the estimate's body pitch. Units: m in the marker frame, N before scaling.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from rftgls_core.types import pull_direction

# margin / capacity at and above which the capacity arrow is fully green.
MARGIN_GREEN = 0.3
GREY = (0.6, 0.6, 0.6, 1.0)
TENSION_RGBA = (0.2, 0.5, 1.0, 1.0)
CURVE_RGBA = (1.0, 0.6, 0.0, 1.0)


@dataclass(frozen=True)
class MarkerStyle:
    """Drawing scales: force_scale_m_per_N turns N into m; twist_length_m is the length of the
    unit slip direction; curve_phis_rad the tether angles sampled for the limit curve."""

    force_scale_m_per_N: float = 0.01
    twist_length_m: float = 0.05
    line_width_m: float = 0.003
    curve_phis_rad: tuple[float, ...] = tuple(np.radians(np.arange(-90.0, 90.5, 2.0)))


@dataclass(frozen=True)
class MarkerGeometry:
    """One marker: kind 'line_strip' | 'arrow' | 'text'; points (n, 3) in m in the marker frame
    (an arrow: tail, head; text: its anchor); rgba in [0, 1]."""

    ns: str
    kind: str
    points: np.ndarray
    rgba: tuple[float, float, float, float]
    width_m: float = 0.003
    text: str = ''


@dataclass(frozen=True)
class CurveSample:
    """The limit curve at My = 0: tether angles (rad), capacities (N, NaN without a value) and
    the force points C d(phi) in world axes (N, columns Fx, Fz)."""

    phis_rad: np.ndarray
    capacity_N: np.ndarray
    forces_N: np.ndarray = field(repr=False)


def limit_curve(predict: Callable[[float], float | None],
                phis_rad: Sequence[float]) -> CurveSample:
    """Sample the capacity C(phi) (predict: phi rad -> N or None) along the given angles."""
    phis = np.asarray(phis_rad, dtype=float)
    caps = np.array([np.nan if (c := predict(float(p))) is None else float(c) for p in phis])
    dirs = np.stack([-np.cos(phis), np.sin(phis)], axis=1)
    return CurveSample(phis, caps, dirs * caps[:, None])


def world_to_body(xz: np.ndarray, theta_b: float) -> np.ndarray:
    """(n, 2) world (x, z) vectors -> (n, 3) body-frame points (x_B, 0, z_B), m or N."""
    xz = np.atleast_2d(np.asarray(xz, dtype=float))
    c, s = math.cos(theta_b), math.sin(theta_b)
    out = np.zeros((xz.shape[0], 3))
    out[:, 0] = xz[:, 0] * c + xz[:, 1] * s
    out[:, 2] = -xz[:, 0] * s + xz[:, 1] * c
    return out


def world_points_to_body(pts: np.ndarray, theta_b: float) -> np.ndarray:
    """(n, 3) world-axis vectors (x, y, z) -> body frame B (the same rotation about y)."""
    pts = np.atleast_2d(np.asarray(pts, dtype=float))
    c, s = math.cos(theta_b), math.sin(theta_b)
    out = np.empty_like(pts)
    out[:, 0] = pts[:, 0] * c + pts[:, 2] * s
    out[:, 1] = pts[:, 1]
    out[:, 2] = -pts[:, 0] * s + pts[:, 2] * c
    return out


def margin_rgba(margin_N: float | None, capacity_N: float | None) -> tuple[float, ...]:
    """Red (no value or margin <= 0) through yellow to green (margin >= MARGIN_GREEN x C)."""
    if margin_N is None or capacity_N is None or not math.isfinite(margin_N) \
            or not math.isfinite(capacity_N) or capacity_N <= 0.0:
        return (1.0, 0.0, 0.0, 1.0)
    x = min(1.0, max(0.0, margin_N / (MARGIN_GREEN * capacity_N)))
    return (min(1.0, 2.0 * (1.0 - x)), min(1.0, 2.0 * x), 0.0, 1.0)


def _finite(x: float | None) -> bool:
    return x is not None and math.isfinite(x)


def estimate_markers(status: str, theta_b: float | None, phi: float | None,
                     capacity_N: float | None, tension_N: float | None,
                     margin_N: float | None, slip_twist: Sequence[float] | None,
                     slipping: bool, curve: CurveSample | None,
                     style: MarkerStyle = MarkerStyle(), h_m: float | None = None,
                     buried_m: np.ndarray | None = None) -> list[MarkerGeometry]:
    """The markers of one estimate (see the module doc). Without a body pitch nothing can be
    placed in the body frame: only the text is returned. A missing value draws nothing.
    h_m: height of p above the free surface (m); buried_m: (n, 3) buried facet centroids
    relative to p in world axes (m)."""
    k = style.force_scale_m_per_N
    lines = [f'{status}']
    if _finite(capacity_N):
        lines.append(f'C {capacity_N:.2f} N')
    if _finite(tension_N):
        lines.append(f'T {tension_N:.2f} N')
    if _finite(margin_N):
        lines.append(f'margin {margin_N:.2f} N')
    if slip_twist is not None and all(_finite(v) for v in slip_twist):
        lines.append(f'slip wy {slip_twist[2]:+.2f}')
    out = [MarkerGeometry('text', 'text', np.array([[0.0, 0.0, 0.06]]), (1.0, 1.0, 1.0, 1.0),
                          0.015, ' | '.join(lines))]
    if not _finite(theta_b):
        return out
    assert theta_b is not None
    if _finite(h_m):
        assert h_m is not None
        line = np.array([[-0.15, 0.0, -h_m], [0.15, 0.0, -h_m]])
        out.append(MarkerGeometry('surface', 'line_strip', world_points_to_body(line, theta_b),
                                  (0.8, 0.7, 0.4, 1.0), style.line_width_m))
    if buried_m is not None and len(buried_m):
        out.append(MarkerGeometry('buried_facets', 'points',
                                  world_points_to_body(buried_m, theta_b), (0.55, 0.35, 0.1, 1.0),
                                  0.002))
    if curve is not None:
        ok = np.isfinite(curve.capacity_N)
        if ok.sum() >= 2:
            out.append(MarkerGeometry('limit_curve', 'line_strip',
                                      world_to_body(curve.forces_N[ok] * k, theta_b), CURVE_RGBA,
                                      style.line_width_m))
    if not _finite(phi):
        return out
    assert phi is not None
    d = np.array(pull_direction(phi)[:2])
    origin = np.zeros(3)
    if _finite(tension_N):
        head = world_to_body(d * tension_N * k, theta_b)[0]
        out.append(MarkerGeometry('tension', 'arrow', np.stack([origin, head]), TENSION_RGBA,
                                  2 * style.line_width_m))
    if _finite(capacity_N):
        head = world_to_body(d * capacity_N * k, theta_b)[0]
        out.append(MarkerGeometry('capacity', 'arrow', np.stack([origin, head]),
                                  margin_rgba(margin_N, capacity_N), style.line_width_m))
    if slip_twist is not None and all(_finite(v) for v in slip_twist):
        v = np.array([slip_twist[0], slip_twist[1]], dtype=float)
        n = float(np.linalg.norm(v))
        if n > 0.0:
            head = world_to_body(v / n * style.twist_length_m, theta_b)[0]
            out.append(MarkerGeometry('slip_twist', 'arrow', np.stack([origin, head]),
                                      (1.0, 0.0, 0.0, 1.0) if slipping else GREY,
                                      style.line_width_m))
    return out
