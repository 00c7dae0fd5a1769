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

4. Nearer exits (closure.py, docs/design/closure.md): a thin-fold check where roots or the
   chord say the surface folds; then `local_exit` around a Newton root, or `jump_exit` (finer
   patches, repeated) around an exit of the closure search. Each replaces the answer only by
   a closer converged exit of the closure.

Limit: a crossing that the coarse mesh misses entirely (a feature thinner than its triangles)
is not seeded. Raise n_twists when the surface has fine folds.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Self

import numpy as np

from ..types import Status
from .base import SUPPORT_CHECK_TWISTS, CapacityResult, FitSamples, GLSProblem, LimitSurface
from .closure import DIRECT_FOLD_CHECK_RTOL, closure_exit, earlier_exit, jump_exit, local_exit
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
        self._dense: tuple[PreparedMesh, TwistSphere] | None = None

    def _fit_samples(self, problem: GLSProblem, samples: FitSamples) -> Self:
        # The coarse sphere only brackets the ray; Newton on wrench_fn does the rest.
        self.sphere = samples.sphere
        self._ws = samples.wrenches_scaled
        self._mesh = prepare_mesh(samples.wrenches_scaled, samples.sphere.faces)
        self._dense = None
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
        assert self._mesh is not None and self.sphere is not None
        r = self._solve_bracketed(phi, self._mesh, self.sphere)
        if r.status is Status.DEGENERATE and r.reason == 'no_root':
            # The coarse mesh is too coarse for this ray (typically a tiny capacity: the origin
            # sits close to the surface, where the chords are poor). Bracket again on the dense
            # sphere of the support check, built once per fit.
            mesh, sphere = self._dense_bracket()
            dense = self._solve_bracketed(phi, mesh, sphere)
            if dense.status.has_value:
                return replace(dense, detail=f'dense bracket ({sphere.n} twists): '
                                             + dense.detail)
        return r

    def _dense_bracket(self) -> tuple[PreparedMesh, TwistSphere]:
        if self._dense is None:
            pr = self._fitted_problem()
            sphere = TwistSphere.build(max(SUPPORT_CHECK_TWISTS, self.n_twists))
            if self.support_samples_ is not None and self.support_samples_[0] is sphere:
                ws = self.support_samples_[1]      # the fit's support check evaluated them
            else:
                self.n_wrench_calls += 1
                ws = pr.scaling.wrench_to_scaled(pr.wrenches(sphere.twists_raw(pr.scaling)))
            self._dense = (prepare_mesh(ws, sphere.faces), sphere)
        return self._dense

    def _solve_bracketed(self, phi: float, mesh: PreparedMesh,
                         sphere: TwistSphere) -> CapacityResult:
        pr = self._fitted_problem()
        d = pr.load_direction_scaled(phi)
        s_c, faces, bary = all_hits(mesh, d)
        calls0 = self.n_wrench_calls
        if len(s_c) == 0:
            return CapacityResult.make(phi, Status.DEGENERATE, self.method, None, n_hits=0,
                                       reason='no_hit', detail='coarse mesh: ray never exits')
        ts = sphere.twists_scaled
        tri = sphere.faces[faces]                                 # (H, 3)
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
        # First exit: the smallest root found from any seed. At the first coarse crossing the
        # ray may pass through a jump of the map (no root there): then the exit is on the
        # closure, found by shrinking patches around that crossing (closure.py).
        on_jump, bridge, searched = False, 0.0, False
        if np.any(valid & (group == 0)):
            k0 = int(np.flatnonzero(valid)[np.argmin(s[valid])])
            s0, t0 = float(s[k0]), t[k0]
        else:
            corners = ts[tri[0]]
            radius = 1.5 * float(np.arccos(np.clip(corners @ seeds[0], -1.0, 1.0)).max()) + 1e-4
            ch = closure_exit(self._eval_scaled, d, seeds[0], radius)
            calls = self.n_wrench_calls - calls0
            if not ch.converged:
                return CapacityResult.make(
                    phi, Status.DEGENERATE, self.method, float(s_c[0]) * sf, n_hits=len(s_c),
                    reason='no_root',
                    detail=base + f'; no twist maps onto the ray at the first crossing and the '
                           f'closure search did not settle ({ch.levels} patches, {calls} wrench '
                           'calls); unchecked value from the coarse mesh')
            s0, t0, on_jump, bridge, searched = ch.s, ch.twist, ch.on_jump, ch.bridge, True
            if np.any(valid) and float(s[valid].min()) < s0:
                k0 = int(np.flatnonzero(valid)[np.argmin(s[valid])])
                s0, t0, on_jump, searched = float(s[k0]), t[k0], False, False
            base += f'; closure search: {ch.levels} patches, {calls} wrench calls in all'
        # A fold sheet thinner than the coarse mesh hides an earlier exit: look for one where
        # the evidence says the surface folds here (several roots, or a chord far off).
        if len(roots) > 1 or abs(s0 - float(s_c[0])) > DIRECT_FOLD_CHECK_RTOL * s0:
            fold = earlier_exit(self._eval_scaled, d, t0, s0)
            if fold is not None:
                base += f'; earlier exit on a thin fold ({s0 * sf:.4g} N further out)'
                s0, t0, on_jump, bridge = fold.s, fold.twist, fold.on_jump, fold.bridge
                searched = True
        if not on_jump and not searched:
            # Newton converges to a smooth root even where the ray crosses a bridged jump a
            # few tenths of a degree in front of it (docs/design/closure.md): a local closure
            # check around the root, one wrench call when there is none.
            near = local_exit(self._eval_scaled, d, t0, s0)
            if near is not None:
                base += (f'; closure exit in front of the Newton root ({s0 * sf:.4g} N '
                         'further out)')
                s0, t0, on_jump, bridge = near.s, near.twist, near.on_jump, near.bridge
        if on_jump or searched:
            # An exit of the closure search (a jump, or Newton failed): where switching
            # circles lie 1e-4 rad apart the search can settle on a crossing that is not the
            # first; finer turned patches around it find the nearer one (closure.jump_exit).
            near = jump_exit(self._eval_scaled, d, t0, s0)
            if near is not None:
                base += f'; nearer closure exit next to the first one ({s0 * sf:.4g} N further out)'
                s0, t0, on_jump, bridge = near.s, near.twist, near.on_jump, near.bridge
        flags: list[str] = ['on_jump'] if on_jump else []
        if on_jump:
            detail = base + (f'; the ray crosses a bridged jump (relative gap {bridge:.2g}): '
                             'the slip twist lies on a facet switching set')
            return CapacityResult.make(phi, Status.OK, self.method, s0 * sf, t0, pr.scaling,
                                       n_hits=len(roots), detail=detail, flags=tuple(flags))
        same = valid & (np.abs(s - s0) <= 1e-7 * s0)
        ang = np.arccos(np.clip(t[same] @ t0, -1.0, 1.0)) if np.any(same) else np.zeros(1)
        k_same = np.flatnonzero(same)
        sv = (np.linalg.svd(jac[k_same[0]], compute_uv=False) if len(k_same)
              else np.array([1.0, 1.0]))   # exit not from Newton: no Jacobian to judge
        detail = base + (f'; Jacobian singular values {sv[0]:.3g}, {sv[1]:.3g}' if len(k_same)
                         else '')
        # Other roots at the same distance with a different twist, or a singular Jacobian: the
        # capacity stands, the slip twist is not unique.
        spread = float(ang.max())
        if spread > 1e-4 or sv[1] < 1e-6 * max(sv[0], 1e-300):
            flags.append('twist_ambiguous')
            detail += f'; several twists give the first-exit wrench (spread {spread:.3g} rad)'
            return CapacityResult.make(phi, Status.OK, self.method, s0 * sf, t0, pr.scaling,
                                       n_hits=len(roots), detail=detail, flags=tuple(flags),
                                       twist_spread_rad=spread)
        if len(roots) > 1:
            flags.append('multiple_crossings')
        return CapacityResult.make(phi, Status.OK, self.method, s0 * sf, t0, pr.scaling,
                                   n_hits=len(roots), detail=detail, flags=tuple(flags))
