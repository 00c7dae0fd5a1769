"""Direct capacity: no surface, solve W_ext(t) = s d(phi), s > 0, for the unit twist t.

The reference every representation is measured against. Working in the scaled spaces, with
d the unit load direction, e1 = (-d_z, d_x, 0) and e2 = (0, 0, 1) spanning the plane normal to
d, a twist t is on the load ray when the two residuals

    r(t) = (e1 . Ws(t), e2 . Ws(t))

vanish (My = 0 and (Fx, Fz) parallel to d), with s = d . Ws(t) > 0.

1. Fit (the base-class template): one batched wrench_fn call on a coarse twist sphere mesh
   (default 400 twists) and its winding number about the origin (origin outside ->
   UNSUPPORTED); here only the ray precompute of that mesh is added.
2. Query: cast the ray on the coarse mesh; every crossing is a bracket whose barycentric twist
   seeds a Newton solve on the sphere (2 unknowns: steps in the tangent plane, re-centred each
   iteration). All seeds advance together; each iteration is ONE wrench_fn call on 3 twists
   per seed (the point and two forward differences), so a query costs about 5-10 batched calls.
   Steps that do not reduce the residual are halved (backtracking).
3. First-exit rule: every crossing seeds its barycentric twist and its face's three vertex
   twists (close crossings of a fold can swap roots); the capacity is the smallest positive
   root found. If no seed of the first coarse crossing converges, that crossing is unresolved
   (a jump or pinch of the map) and the result is DEGENERATE: no later root is reported in
   its place. Several distinct twists at the same first-exit distance, or a
   singular 2x2 Jacobian there, mean the twist-wrench pair is not unique: DEGENERATE.
   Several crossings at different distances: the smallest is the capacity (reported in n_hits
   and detail, status ok: the load ramps from zero, so the first crossing starts the slip).

Limit: a crossing that the coarse mesh misses entirely (a feature thinner than its triangles)
is not seeded. Raise n_twists when the surface has fine folds.
"""
from __future__ import annotations

from typing import Self

import numpy as np

from ..types import Status
from .base import CapacityResult, FitSamples, GLSProblem, LimitSurface
from .newton import newton_on_sphere, unit_rows
from .raycast import PreparedMesh, all_hits, prepare_mesh
from .twist_sphere import TwistSphere


class DirectSurface(LimitSurface):
    """Root-finding reference. n_twists: coarse bracketing sphere (default 400).

    rtol: residual tolerance relative to the first-exit distance (scaled units).
    fd_step: forward-difference step on the twist sphere, rad.
    """

    method = 'direct'

    def __init__(self, n_twists: int = 400, rtol: float = 1e-12, fd_step: float = 1e-7,
                 max_iter: int = 40, gap_tol: float = 2e-3) -> None:
        super().__init__(n_twists)
        self.rtol, self.fd_step, self.max_iter = float(rtol), float(fd_step), int(max_iter)
        self.gap_tol = float(gap_tol)
        self.n_wrench_calls = 0
        self.sphere: TwistSphere | None = None
        self._mesh: PreparedMesh | None = None

    def _fit_samples(self, problem: GLSProblem, samples: FitSamples) -> Self:
        # The coarse sphere only brackets the ray; Newton on wrench_fn does the rest.
        self.sphere = samples.sphere
        self._ws = samples.wrenches_scaled
        self._mesh = prepare_mesh(samples.wrenches_scaled, samples.sphere.faces)
        return self

    # -- the solver ------------------------------------------------------------------------
    def _eval_scaled(self, ts: np.ndarray) -> np.ndarray:
        self.n_wrench_calls += 1
        pr = self._fitted_problem()
        return pr.scaling.wrench_to_scaled(pr.wrenches(pr.scaling.twist_from_scaled(ts)))

    def solve(self, d: np.ndarray, seeds: np.ndarray):
        """Newton on the sphere from seeds (K, 3). Returns (t, s, resid, J, converged, iters)."""
        return newton_on_sphere(self._eval_scaled, d, seeds, self.rtol, self.fd_step,
                                self.max_iter)

    def _capacity(self, phi: float) -> CapacityResult:
        pr = self._fitted_problem()
        assert self._mesh is not None and self.sphere is not None
        d = pr.load_direction_scaled(phi)
        s_c, faces, bary = all_hits(self._mesh, d)
        calls0 = self.n_wrench_calls
        if len(s_c) == 0:
            return CapacityResult.make(phi, Status.DEGENERATE, self.method, None, n_hits=0,
                                       reason='no_hit', detail='coarse mesh: ray never exits')
        ts = self.sphere.twists_scaled
        tri = self.sphere.faces[faces]                                 # (H, 3)
        # Seeds: the barycentric twist of every coarse crossing plus the three vertex twists
        # of its face (close crossings of a fold can swap roots; extra seeds find them all).
        seeds = np.concatenate([unit_rows(np.einsum('hk,hkj->hj', bary, ts[tri])),
                                ts[tri].reshape(-1, 3)])
        group = np.concatenate([np.arange(len(s_c)), np.repeat(np.arange(len(s_c)), 3)])
        t, s, res, jac, conv, iters = self.solve(d, seeds)
        sf = pr.scaling.force_N
        # RFT's wrench map has small jumps (facets switching between leading and trailing), so
        # the ray can pass through a gap no twist maps onto exactly: accept the closest twist
        # when the miss is below gap_tol of the distance (the capacity is then that precise).
        gap = ~conv & (res <= self.gap_tol * np.maximum(np.abs(s), 1e-3))
        valid = (conv | gap) & (s > 0.0)
        calls = self.n_wrench_calls - calls0
        roots = np.unique(np.round(s[valid] / (1e-7 * max(float(s_c[-1]), 1e-300))))
        base = (f'coarse crossings {len(s_c)}, distinct roots {len(roots)}, iterations {iters}, '
                f'wrench calls {calls}')
        if not np.any(valid & (group == 0)) or not np.any(valid):
            return CapacityResult.make(
                phi, Status.DEGENERATE, self.method, float(s_c[0]) * sf, n_hits=len(s_c),
                reason='no_root',
                detail=base + '; no twist maps onto the ray at the first crossing (a jump or '
                       'pinch in the twist-wrench map); unchecked value from the coarse mesh')
        # First exit: the smallest root found from any seed.
        k0 = int(np.flatnonzero(valid)[np.argmin(s[valid])])
        s0, t0 = float(s[k0]), t[k0]
        sv = np.linalg.svd(jac[k0], compute_uv=False)
        detail = (base + f'; residual {res[k0]:.1e}, Jacobian singular values {sv[0]:.3g}, '
                  f'{sv[1]:.3g}')
        # Other roots at the same distance with a different twist: not one-to-one.
        same = valid & (np.abs(s - s0) <= 1e-7 * s0)
        ang = np.arccos(np.clip(t[same] @ t0, -1.0, 1.0))
        if np.any(ang > 1e-4) or sv[1] < 1e-6 * max(sv[0], 1e-300):
            return CapacityResult.make(
                phi, Status.DEGENERATE, self.method, s0 * sf, t0, pr.scaling,
                n_hits=len(roots), reason='non_unique_twist',
                detail=detail + '; several twists give the first-exit wrench')
        return CapacityResult.make(phi, Status.OK, self.method, s0 * sf, t0, pr.scaling,
                                   n_hits=len(roots), detail=detail)
