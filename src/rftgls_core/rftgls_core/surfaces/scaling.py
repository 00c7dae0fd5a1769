"""Per-axis scaling that makes planar wrenches and twists dimensionless before any geometry.

Raw planar wrenches W = (Fx, Fz, My) are in (N, N, N m) and raw twists t = (vx, vz, wy) in
(m/s, m/s, rad/s), both in world axes about the winch point p. Geometry (Delaunay, alpha radii,
sphere sampling, angles between twists) is meaningless across mixed units, so every surface
works in the scaled spaces

    Ws = W / S,      ts = S t / |S t|,      S = diag(s_F, s_F, s_F * L_c),

which keeps the power pairing: t . W = (S t) . (S^-1 W), so ts . Ws is t . W times a positive
factor. Normality and barycentric reasoning therefore carry over unchanged.

Both force axes share one scale s_F on purpose: the load ray d(phi) lies in the (Fx, Fz)
plane, and a common force scale keeps its direction (and so pull angles) unchanged by scaling.
A load of magnitude F along d(phi) is the scaled point (F / s_F) d(phi).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .newton import unit_rows
from .sampling import fibonacci_sphere


@dataclass(frozen=True)
class DiagonalScaling:
    """Force scale s_F (N) and length L_c (m) of a scaled wrench/twist space with the diagonal
    scale S = `diag` (forces by s_F, moments by s_F L_c): the planar `Scaling` here and the
    spatial gls6d.Scaling6 differ only in S."""

    force_N: float
    length_m: float

    def __post_init__(self) -> None:
        for name, v in (('force scale', self.force_N), ('length scale', self.length_m)):
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f'{name} must be finite and > 0, got {v!r}')

    @property
    def diag(self) -> np.ndarray:
        raise NotImplementedError

    # -- wrenches ---------------------------------------------------------------------------
    def wrench_to_scaled(self, wrench: np.ndarray) -> np.ndarray:
        """(..., n) raw wrenches (N, N m) -> dimensionless W / S."""
        return np.asarray(wrench, dtype=float) / self.diag

    def wrench_from_scaled(self, wrench_s: np.ndarray) -> np.ndarray:
        return np.asarray(wrench_s, dtype=float) * self.diag

    # -- twists -----------------------------------------------------------------------------
    def twist_to_scaled(self, twist: np.ndarray) -> np.ndarray:
        """(..., n) raw twists (m/s, rad/s) -> unit scaled twists ts = S t / |S t|.

        Only the direction matters (RFT is rate independent); S t is (v, w L_c) times s_F.
        """
        return unit_rows(np.asarray(twist, dtype=float) * self.diag)

    def twist_from_scaled(self, twist_s: np.ndarray) -> np.ndarray:
        """(..., n) scaled twists -> raw twist directions S^-1 ts, normalised to |t| = 1.

        The raw norm mixes m/s and rad/s; it is only a convention to return a direction with a
        fixed size. Compare twists in the scaled metric, never with raw angles.
        """
        return unit_rows(np.asarray(twist_s, dtype=float) / self.diag)


@dataclass(frozen=True)
class Scaling(DiagonalScaling):
    """Force scale s_F (N) and characteristic length L_c (m) of the scaled wrench/twist spaces."""

    @property
    def diag(self) -> np.ndarray:
        """S = (s_F, s_F, s_F L_c) in (N, N, N m)."""
        return np.array([self.force_N, self.force_N, self.force_N * self.length_m])

    # -- choosing the scales from data ------------------------------------------------------
    @classmethod
    def from_wrenches(cls, wrenches: np.ndarray, floor_N: float = 1e-9,
                      floor_m: float = 1e-9) -> 'Scaling':
        """Half-range scaling of a raw W_ext cloud (M, 3).

        s_F = the larger half-range of Fx and Fz (one scale for both force axes, see module
        doc), L_c = half-range(My) / s_F, so the scaled cloud spans about [-1, 1] on the
        larger force axis and on the moment axis. Half-ranges, not standard deviations: the
        cloud samples a surface, and its extent is what geometry tolerances must match.
        Floors keep a flat cloud (e.g. My constant) from producing a zero scale.
        """
        w = np.asarray(wrenches, dtype=float)
        if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2 or not np.all(np.isfinite(w)):
            raise ValueError('wrenches must be a finite (M>=2, 3) array')
        half = 0.5 * (w.max(axis=0) - w.min(axis=0))
        s_f = max(float(half[0]), float(half[1]), floor_N)
        l_c = max(float(half[2]) / s_f, floor_m)
        return cls(s_f, l_c)


def choose_scaling(wrench_fn, length_guess_m: float, n_pilot: int = 256,
                   force_guess_N: float = 1.0) -> Scaling:
    """Data-driven scaling from a pilot sample of wrench_fn.

    The twist sample itself depends on L_c (uniform in the scaled twist metric), so a pilot of
    n_pilot twists is drawn with L_c = length_guess_m (e.g. the leg length), and the final
    scaling is the half-range scaling of the resulting W_ext cloud (Scaling.from_wrenches).
    One batched wrench_fn call.
    """
    pilot = Scaling(force_guess_N, length_guess_m)
    twists = pilot.twist_from_scaled(fibonacci_sphere(n_pilot))
    return Scaling.from_wrenches(np.asarray(wrench_fn(twists), dtype=float))
