"""Treers, Cao & Stuart 2021 (RA-L 6(2)) 3D RFT: Li's 2D fit applied in each facet's plane.

Per facet with outward unit normal n and unit velocity direction v (world axes, z up), as in
Treers' rft_3D_body (docs/design/models-rft.md):
- e2: the normalised horizontal projection of n. For a near-horizontal facet
  (|n_z| >= 1 - flat_tol) that direction is noise, so e2 is the horizontal projection of v
  instead: the facet then behaves exactly like Li's 2D plate in the plane of motion.
- e1 = e2 x z_hat: horizontal, normal to the vertical plane (e2, z) that holds n.
- v = v1 + v23 with v1 = (v . e1) e1 (out-of-plane sliding) and v23 in the (e2, z) plane.
- beta, gamma: Li's angles of the facet's plate line and of v23 in that plane, x_hat = e2.
- weights f1(|v1|) and f23(|v23|) (section 3.3), both 0 at 0 and 1 at 1.
- stress per depth: s = -f1 alpha_1 sign(v . e1) e1 - f23 alpha_x e2 + f23 alpha_z z_hat.

Deviations from the public MATLAB, all deliberate:
- Degenerate directions are resolved with np.where selects, never by arithmetic blending, so
  no NaN can leak (the public code returns NaN for exactly horizontal facets, 3.5). A facet
  with no horizontal normal and a vertical velocity keeps e2 = x_hat (any e2 gives the same
  stress there because alpha_x(0, +-pi/2) = 0). Treers' (1e-5, 0, 0) nudge of v is not used.
- beta and gamma never materialise as angles: the fit is evaluated from cos/sin of 2 beta and
  gamma built from dot products, which is exact, branch-cut free and cheaper.
- alpha_1 defaults to Li's alpha_x(0, 0) of the chosen set (0.136 zeta for the generic set,
  the "simplest form" in Treers' code comment and qishuny/3D-RFT-wheel). Treers' code uses
  0.2035 (a linear fit whose slope term is a unit slip, 3.4); pass alpha1_ratio=0.2035 to
  reproduce it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .li import N_PER_CM3, LiCoefficients, coefficient_set

# f1(vt) = c1 [tanh(c2 vt - c3) + tanh(c3)] / c4 (docs/design/models-rft.md, rft_3D_body.m)
F1_C = (0.440850096954369, 3.62263982880971, 1.60910808139526, 0.832324700111401)
# f23(vn) = d1 [artanh(d2 vn - d3) + artanh(d3)] / d4
F23_D = (1.99392673405210, 1.61146827229181, 0.973746396532650, 5.81083560370960)
# |n_z| >= 1 - FLAT_TOL marks a near-horizontal facet (Treers' threshold).
FLAT_TOL = 1e-3
# Below this a direction (horizontal projection, in-plane velocity) is treated as absent.
_TINY = 1e-12


def f1(vt: np.ndarray) -> np.ndarray:
    """Weight of the out-of-plane sliding stress; vt = |v . e1| in [0, 1] (clipped)."""
    c1, c2, c3, c4 = F1_C
    vt = np.clip(vt, 0.0, 1.0)
    return c1 * (np.tanh(c2 * vt - c3) + math.tanh(c3)) / c4


def f23(vn: np.ndarray) -> np.ndarray:
    """Weight of the in-plane (Li 2D) stress; vn = |v23| in [0, 1] (clipped)."""
    d1, d2, d3, d4 = F23_D
    vn = np.clip(vn, 0.0, 1.0)
    # d2 - d3 < 1 and -d3 > -1, so the argument is inside artanh's domain; the clip only
    # guards against a future change of constants.
    arg = np.clip(d2 * vn - d3, -1.0 + 1e-15, 1.0 - 1e-15)
    return d1 * (np.arctanh(arg) + math.atanh(d3)) / d4


@dataclass(frozen=True)
class Decomposition:
    """Treers' per-facet split of unit velocity directions, arrays of shape (M, F).

    e2x, e2y: horizontal in-plane axis e2 (e1 = (e2y, -e2x, 0)); v1: v . e1 (signed);
    vt, vn: |v1| and |v23| normalised so vt^2 + vn^2 = 1 (both 0 for a zero input);
    cos2b, sin2b: of Li's beta of the facet's plate line; cosg, sing: of Li's gamma of v23.
    """

    e2x: np.ndarray
    e2y: np.ndarray
    v1: np.ndarray
    vt: np.ndarray
    vn: np.ndarray
    cos2b: np.ndarray
    sin2b: np.ndarray
    cosg: np.ndarray
    sing: np.ndarray


@dataclass(frozen=True)
class TreersFrames:
    """Per-facet constants of the decomposition for F outward unit normals (world axes).

    For a facet that is not near-horizontal, e2 and beta depend on the normal only and are
    cached here; near-horizontal facets (flat_idx) get them per velocity in decompose().
    """

    normals: np.ndarray     # (F, 3), renormalised (zero rows stay zero)
    flat_idx: np.ndarray    # indices of near-horizontal facets: e2 follows the velocity
    e2x: np.ndarray         # (F,) static e2 (normal's horizontal direction, else x_hat)
    e2y: np.ndarray
    cos2b: np.ndarray       # (F,) of Li's beta with the static e2
    sin2b: np.ndarray

    @classmethod
    def from_normals(cls, normals: np.ndarray, flat_tol: float = FLAT_TOL) -> 'TreersFrames':
        n = np.asarray(normals, dtype=float)
        if n.ndim != 2 or n.shape[1] != 3:
            raise ValueError(f'normals must have shape (F, 3), got {n.shape}')
        if not np.all(np.isfinite(n)):
            raise ValueError('normals must be finite')
        norm = np.linalg.norm(n, axis=1)
        n = n / np.where(norm > 0.0, norm, 1.0)[:, None]
        nh = np.hypot(n[:, 0], n[:, 1])
        has_h = nh > _TINY
        safe = np.where(has_h, nh, 1.0)
        e2x = np.where(has_h, n[:, 0] / safe, 1.0)
        e2y = np.where(has_h, n[:, 1] / safe, 0.0)
        cos2b, sin2b = _plate_line(n[:, 0] * e2x + n[:, 1] * e2y, n[:, 2])
        flat_idx = np.flatnonzero(np.abs(n[:, 2]) >= 1.0 - flat_tol)
        return cls(n, flat_idx, e2x, e2y, cos2b, sin2b)

    def decompose(self, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray) -> Decomposition:
        """Split velocity directions (M, F) (or broadcastable to it) per facet."""
        shape = np.broadcast_shapes(np.shape(vx), np.shape(vy), np.shape(vz),
                                    self.e2x.shape)
        vx, vy, vz = (np.broadcast_to(np.asarray(a, dtype=float), shape) for a in (vx, vy, vz))
        e2x, e2y = np.broadcast_to(self.e2x, shape), np.broadcast_to(self.e2y, shape)
        cos2b, sin2b = self.cos2b, self.sin2b
        k = self.flat_idx
        if k.size:
            # flat facets take e2 from the velocity's horizontal direction when it has one
            fx, fy = vx[..., k], vy[..., k]
            vh = np.sqrt(fx * fx + fy * fy)
            follow = vh > _TINY
            vh_safe = np.where(follow, vh, 1.0)
            kx = np.where(follow, fx / vh_safe, self.e2x[k])
            ky = np.where(follow, fy / vh_safe, self.e2y[k])
            e2x, e2y = e2x.copy(), e2y.copy()
            e2x[..., k], e2y[..., k] = kx, ky
            n = self.normals[k]
            kc, ks = _plate_line(n[:, 0] * kx + n[:, 1] * ky, np.broadcast_to(n[:, 2], kx.shape))
            cos2b = np.broadcast_to(cos2b, shape).copy()
            sin2b = np.broadcast_to(sin2b, shape).copy()
            cos2b[..., k], sin2b[..., k] = kc, ks
        v1 = vx * e2y - vy * e2x                 # v . e1, e1 = e2 x z = (e2y, -e2x, 0)
        v2 = vx * e2x + vy * e2y                 # v . e2
        # gamma of v23 = (v2, vz): v23 = |v23| (cos g e2 - sin g z)
        vn = np.sqrt(v2 * v2 + vz * vz)
        has_n = vn > _TINY
        inv_n = np.where(has_n, 1.0 / np.where(has_n, vn, 1.0), 0.0)
        cosg = np.where(has_n, v2 * inv_n, 1.0)
        sing = -vz * inv_n
        # unit split even if the input is not exactly unit; zero input -> no stress
        vt = np.abs(v1)
        total = np.sqrt(vt * vt + vn * vn)
        has_v = total > _TINY
        inv_t = np.where(has_v, 1.0 / np.where(has_v, total, 1.0), 0.0)
        return Decomposition(e2x, e2y, v1, vt * inv_t, vn * inv_t, cos2b, sin2b, cosg, sing)


def _plate_line(p: np.ndarray, nz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos 2 beta, sin 2 beta of the plate line whose normal projects to (p, nz) on (e2, z).

    Li's n_d is +-(p, nz) normalised; cos 2b = nz^2 - p^2 and sin 2b = -2 p nz hold for
    either sign, so the face that leads never matters here (it is encoded in gamma).
    """
    q2 = p * p + nz * nz
    has_q = q2 > _TINY
    inv = np.where(has_q, 1.0 / np.where(has_q, q2, 1.0), 0.0)
    return np.where(has_q, (nz * nz - p * p) * inv, 1.0), -2.0 * p * nz * inv


class LiTreersRFT:
    """Li 2013 2D RFT inside Treers 2021's 3D decomposition (a StressModel, rft/base.py).

    zeta: N/m^3, the medium scale; every set's fit numbers are multiplied by it:
      alpha = zeta * alpha^set(beta, gamma).
      - 'generic' (dimensionless, normalised): zeta is the stress per unit depth on a
        horizontal plate pushed straight down, alpha_z(0, pi/2). Required.
      - 'poppy_lp' / 'poppy_cp' (numbers in N/cm^3): they are the stress for zeta = 1 N/cm^3
        = 1e6 N/m^3, which is the default, so the set converts to SI unchanged
        (penetration 0.254e6 / 0.464e6 N/m^3). Another zeta scales it by zeta / 1e6.
    coefficients: 'generic', 'poppy_lp', 'poppy_cp' or a LiCoefficients.
    alpha1_ratio: out-of-plane coefficient alpha_1 / zeta; default: the set's alpha_x(0, 0)
      (0.136 for generic, 0.031 for poppy_lp, 0.065 for poppy_cp).
    flat_tol: facets with |n_z| >= 1 - flat_tol take e2 from the velocity.
    """

    name = 'li'

    def __init__(self, zeta: float | None = None,
                 coefficients: str | LiCoefficients = 'generic',
                 alpha1_ratio: float | None = None, flat_tol: float = FLAT_TOL) -> None:
        coeffs = coefficient_set(coefficients)
        if coeffs.unit == 'N/cm^3':
            # the numbers are N/cm^3 at unit scale: 1 N/cm^3 = 1e6 N/m^3 reproduces them
            zeta = N_PER_CM3 if zeta is None else zeta
        elif coeffs.unit != 'dimensionless':
            raise ValueError(f'unknown coefficient unit {coeffs.unit!r}')
        if zeta is None:
            raise ValueError(f'zeta (N/m^3) is required for the {coeffs.name!r} set')
        zeta = float(zeta)
        if not (math.isfinite(zeta) and zeta > 0.0):
            raise ValueError(f'zeta must be a positive finite number (N/m^3), got {zeta!r}')
        if not 0.0 <= flat_tol < 1.0:
            raise ValueError(f'flat_tol must be in [0, 1), got {flat_tol!r}')
        ratio = coeffs.drag if alpha1_ratio is None else float(alpha1_ratio)
        if not (math.isfinite(ratio) and ratio >= 0.0):
            raise ValueError(f'alpha1_ratio must be finite and >= 0, got {alpha1_ratio!r}')
        self.zeta = zeta
        self.coefficients = coeffs
        self.alpha1 = ratio * zeta            # N/m^3
        self.alpha1_ratio = ratio
        self.flat_tol = float(flat_tol)

    @property
    def penetration(self) -> float:
        """alpha_z(0, pi/2) in N/m^3: stress per depth on a horizontal plate pushed down."""
        return self.zeta * self.coefficients.penetration

    def prepare(self, normals: np.ndarray) -> 'PreparedLiTreers':
        """Bind to outward unit normals (F, 3), world axes."""
        return PreparedLiTreers(self, TreersFrames.from_normals(normals, self.flat_tol))

    def describe(self) -> dict:
        c = self.coefficients
        return {
            'name': self.name,
            'model': 'Li 2013 2D RFT in the Treers 2021 3D decomposition',
            'coefficients': c.name,
            'coefficient_unit': c.unit,
            'coefficient_values': {k: v for k, v in c.as_dict().items()
                                   if k not in ('name', 'unit', 'source')},
            'zeta_N_per_m3': self.zeta,
            'penetration_N_per_m3': self.penetration,
            'alpha1_N_per_m3': self.alpha1,
            'alpha1_ratio': self.alpha1_ratio,
            'flat_tol': self.flat_tol,
            'f1_c': list(F1_C),
            'f23_d': list(F23_D),
            'stress_unit': 'N/m^3',
        }

    def __repr__(self) -> str:
        return (f'LiTreersRFT(zeta={self.zeta:g}, coefficients={self.coefficients.name!r}, '
                f'alpha1_ratio={self.alpha1_ratio:g})')


class PreparedLiTreers:
    """LiTreersRFT bound to F facet normals (a PreparedStress, rft/base.py)."""

    def __init__(self, model: LiTreersRFT, frames: TreersFrames) -> None:
        self.model = model
        self.frames = frames

    def stress(self, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stress per depth (ax, ay, az) in N/m^3, world axes, for unit velocity directions
        of shape (M, F). Assumes the facet leads (the engine masks trailing ones); finite for
        every finite input, zero for a zero velocity."""
        d = self.frames.decompose(vx, vy, vz)
        alpha_x, alpha_z = self.model.coefficients.alpha_cs(d.cos2b, d.sin2b, d.cosg, d.sing)
        w23 = f23(d.vn) * self.model.zeta
        w1 = f1(d.vt) * self.model.alpha1 * np.sign(d.v1)
        # s = -w1 e1 - w23 alpha_x e2 + w23 alpha_z z, with e1 = (e2y, -e2x, 0)
        ax = -w1 * d.e2y - w23 * alpha_x * d.e2x
        ay = w1 * d.e2x - w23 * alpha_x * d.e2y
        az = w23 * alpha_z
        return ax, ay, az
