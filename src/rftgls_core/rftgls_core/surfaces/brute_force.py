"""Brute-force reference: first exit of the load ray from densely sampled twists, refined locally.

No root finding, no smoothing and no jump detection: only sampling and flat triangles.

1. Global: ~10^5 twists on the sphere, their wrenches as the vertices of the sphere's
   triangulation, and every crossing of the ray with those flat triangles. A triangle that
   straddles a facet switching circle spans the jump, so the mesh is a polyhedral
   approximation of the closure of the RFT map (closure.py).
2. Local refinement: a uniform mesh is an inner approximation where the surface bulges out
   (its chords cut the bulge off), and next to a jump its error falls only linearly with the
   twist spacing (the straddling triangles' vertices lie up to one spacing from the switching
   circle, where the wrench changes by ~20 N/rad). A capacity much smaller than the jump is
   then off by a large fraction: 10^5 twists gave 0.0435 N where the exit is at 0.0506 N.
   So each global crossing that can be the first exit is re-sampled on a sequence of square
   patches of the tangent plane (REFINE_GRID x REFINE_GRID twists, triangulated), each one
   REFINE_RATIO times smaller than the last and centred on the previous patch's hit, from
   3 global spacings down to ~1e-6 rad. The capacity is the smallest refined crossing.
3. Its own error: `errors_N_` (one per query, N) is the change of the distance over the last
   refinement step. Chord errors fall at least linearly with the spacing (quadratically on
   smooth parts), so with the spacing cut by REFINE_RATIO the remaining error of the last
   level is at most that change / (REFINE_RATIO - 1); the reported bound keeps the whole
   change (a factor REFINE_RATIO - 1 of margin). Where a patch loses the crossing (the hit
   leaves it twice) the error is the spread of the levels reached, and `detail` says so.

Independent of `direct` (Newton, closure.py's patch search and its acceptance rules) and of
`twist-mesh`: it shares only the ray-triangle routine and the wrench function. Slow (1-2 s
per state) by design.
"""
from __future__ import annotations

import math
from typing import Self

import numpy as np

from ..types import Status
from .base import CapacityResult, FitSamples, GLSProblem, LimitSurface
from .newton import _tangent_basis, unit_rows
from .raycast import PreparedMesh, all_hits, cast_rays, prepare_mesh
from .twist_sphere import TwistSphere

REFINE_GRID = 33          # twists per side of a refinement patch
REFINE_RATIO = 4.0        # each patch is this many times smaller than the one before
REFINE_FINAL_RAD = 1e-6   # stop when the patch spacing is below this (rad)
MAX_REFINED_CROSSINGS = 6


def _grid_faces(k: int) -> np.ndarray:
    """Two triangles per cell of a k x k grid of points indexed i * k + j."""
    i, j = np.meshgrid(np.arange(k - 1), np.arange(k - 1), indexing='ij')
    a = (i * k + j).ravel()
    b, c, e = a + k, a + k + 1, a + 1
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, e])])


_G = np.linspace(-1.0, 1.0, REFINE_GRID)
_GA, _GB = (g.ravel() for g in np.meshgrid(_G, _G, indexing='ij'))
_GFACES = _grid_faces(REFINE_GRID)


class BruteForceSurface(LimitSurface):
    """Dense twist-sphere mesh, first exit, refined by local re-sampling. n_twists: 100,000.

    refine: False gives the bare uniform mesh (an inner approximation; kept for comparison).
    After each query, `errors_N_` holds the estimated error bound of every returned capacity.
    """

    method = 'brute-force'
    min_twists = 8

    def __init__(self, n_twists: int = 100_000, refine: bool = True) -> None:
        super().__init__(n_twists)
        self.refine = bool(refine)
        self._mesh: PreparedMesh | None = None
        self._sphere: TwistSphere | None = None
        self.errors_N_: list[float | None] = []

    def _fit_samples(self, problem: GLSProblem, samples: FitSamples) -> Self:
        self._sphere = samples.sphere
        self._mesh = prepare_mesh(samples.wrenches_scaled, samples.sphere.faces)
        self.fit_info.detail = f'{samples.sphere.n} twists, {len(samples.sphere.faces)} faces'
        return self

    def _eval_scaled(self, ts: np.ndarray) -> np.ndarray:
        pr = self._fitted_problem()
        return pr.scaling.wrench_to_scaled(pr.wrenches(pr.scaling.twist_from_scaled(ts)))

    def _refine(self, d: np.ndarray, twist: np.ndarray, radius: float
                ) -> tuple[float, float, np.ndarray, str]:
        """Re-sample shrinking patches around `twist`: (distance, error bound, twist, note)."""
        centre, r = unit_rows(np.asarray(twist, dtype=float).reshape(1, 3))[0], float(radius)
        levels: list[float] = []
        misses = 0
        while True:
            u, v = _tangent_basis(centre[None, :])
            pts = unit_rows(centre + r * (_GA[:, None] * u + _GB[:, None] * v))
            hit = cast_rays(prepare_mesh(self._eval_scaled(pts), _GFACES), d)
            f = int(hit.face[0])
            if f < 0:
                misses += 1        # the crossing left the patch: widen once, then give up
                if misses > 1 or not levels:
                    break
                r *= REFINE_RATIO
                continue
            levels.append(float(hit.s[0]))
            centre = unit_rows((hit.bary[0] @ pts[_GFACES[f]])[None, :])[0]
            if 2.0 * r / (REFINE_GRID - 1) < REFINE_FINAL_RAD:
                break
            r /= REFINE_RATIO
        if len(levels) < 2:
            return math.nan, math.nan, centre, 'refinement lost the crossing'
        if misses > 1:
            return (levels[-1], float(np.ptp(levels[-3:])), centre,
                    f'{len(levels)} levels, then a patch lost the crossing: error = spread of '
                    'the last levels')
        return levels[-1], abs(levels[-1] - levels[-2]), centre, f'{len(levels)} levels'

    def _capacity_many(self, phis: np.ndarray) -> list[CapacityResult]:
        pr = self._fitted_problem()
        assert self._mesh is not None and self._sphere is not None
        ts, faces = self._sphere.twists_scaled, self._sphere.faces
        spacing = math.sqrt(4.0 * math.pi / self._sphere.n)
        sf = pr.scaling.force_N
        out: list[CapacityResult] = []
        errors: list[float | None] = []
        for phi in phis:
            d = pr.load_direction_scaled(phi)
            s_c, f_c, bary = all_hits(self._mesh, d)
            if len(s_c) == 0:
                out.append(CapacityResult.make(phi, Status.DEGENERATE, self.method, None,
                                               n_hits=0, reason='no_hit',
                                               detail='ray never leaves the dense mesh'))
                errors.append(None)
                continue
            twists = unit_rows(np.einsum('hk,hkj->hj', bary, ts[faces[f_c]]))
            best, err, tw, note = float(s_c[0]), math.nan, twists[0], 'not refined'
            if self.refine:
                best = math.inf
                for k in range(min(len(s_c), MAX_REFINED_CROSSINGS)):
                    if s_c[k] >= best:
                        break      # chords of later crossings lie beyond the refined exit
                    s_k, e_k, t_k, n_k = self._refine(d, twists[k], 3.0 * spacing)
                    if math.isfinite(s_k) and s_k < best:
                        best, err, tw, note = s_k, e_k, t_k, f'crossing {k + 1}: {n_k}'
                if not math.isfinite(best):
                    best, err, tw = float(s_c[0]), math.nan, twists[0]
                    note = 'refinement failed: bare mesh value, error unknown'
            nh = len(s_c)
            out.append(CapacityResult.make(
                phi, Status.OK, self.method, best * sf, tw, pr.scaling, n_hits=nh,
                detail=f'hits {nh}; {note}; error bound {err * sf:.2g} N',
                flags=('multiple_crossings',) if nh > 1 else ()))
            errors.append(err * sf if math.isfinite(err) else None)
        self.errors_N_ = errors
        return out
