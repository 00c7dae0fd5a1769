"""Warm-started `direct` over a stream of states: the previous exit seeds the next solve.

A robot that streams its state at 100-1000 Hz moves its limit surface by little between two
messages, so the exit twist of the last answer is an excellent Newton seed for the next one:
a warm step costs the pose, one small wrench call for the guards and two to four Newton
iterations (3 twists each) instead of the 400-twist bracketing sphere, its checks and, near
the support edge, the 8,000-twist support check. The reasoning, the guards and their limits are
on docs/design/warm-direct.md.

The contract: a warm answer equals the cold `direct` answer (`DirectSurface(n_twists).fit(
problem).capacity(phi)`) to the solver tolerance, status included. Warm steps are only taken
next to an *anchor*, the last cold solve, and only while nothing the cold solve decided can
have changed:

* the anchor is clean: status ok, one coarse crossing, one root found by Newton (no closure
  search, no dense bracket, no earlier exit on a fold, no flag);
* guards (status, a new first exit): the coarse (and, when the anchor evaluated it, the dense
  support-check) mesh triangles nearest the origin and the load-ray segment are re-evaluated at
  every step; none may close in by more than `clearance_fraction` of its clearance, and the
  typical motion of their vertices must stay below that fraction of the nearest other one;
* the new root is a converged Newton root, its twist within `max_twist_drift_rad` and its
  distance within `max_capacity_change` of the anchor's;
* the cold solve's view around the exit: the coarse triangles there cast again give one
  crossing, its thin-fold search (where the chord is far) finds no earlier sheet, and no jump
  triangle lies in front of the root;
* no jump crossed or next to the root: the residual derivative within `max_jacobian_change` of
  the previous answer's, and the map linear to `ring_tol` on a ring of `ring_rad` around it;
* no crossing of the cold solve's local closure check (closure.local_exit: three small patches
  around the root) in front of the root;
* the pull angle within `max_phi_change_rad` of the anchor's (its swing of the guarded ray
  segment is added to the guards' motion);
* the cold solve's own four seeds (the crossed coarse triangle's barycentric and vertex
  twists), run in the same batched Newton as the warm seed, all reach the warm root: the cold
  answer is the nearest root any of them reaches, and near a jump gap or a second sheet one
  of them can end on a nearer one that no local probe around the warm root sees.

Anything else falls back to the cold solve, which becomes the next anchor when it is clean.
A state parked next to a jump (its warm attempts refused `patience` times in a row) takes
`rest_steps` cold steps without building anchors: there an anchor costs as much as the cold
solve and the next attempt is refused again (docs/design/warm-direct.md, "Parked states").
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from ..types import Status
from .base import CapacityResult, GLSProblem
from .closure import (
    _CU,
    _CV,
    _FACES_LOCAL_ALL,
    DIRECT_FOLD_CHECK_RTOL,
    LOCAL_RTOL,
    earlier_exit,
    local_patches,
)
from .direct import DirectSurface
from .newton import unit_rows
from .warm_guards import ray_hits, triangle_clearance, triangle_clearances
from .warm_kernels import HAVE_NUMBA, guard_use_loop, patch_twists, ray_hits_loop
from .warm_newton import fd_batch, newton_batch, newton_one, scaled_evaluator, tangent_jacobian

# Directions of the ring probe around a warm root (unit vectors of the tangent plane).
_RING = np.column_stack([np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)])
# Samples of the load-ray segment (0, s] whose clearance the guards keep.
_SEGMENT_POINTS = 12


@dataclass(frozen=True)
class _Anchor:
    """What a clean cold solve leaves for the warm steps after it (scaled spaces)."""

    phi: float
    s: float                    # exit distance along d
    twist: np.ndarray           # (3,) exit twist, unit
    jacobian: np.ndarray        # (2, 3) residual derivative at the exit (tangent_jacobian)
    guard_twists: np.ndarray    # (G, 3) unit twists of the guard vertices
    guard_wrenches: np.ndarray  # (G, 3) their wrenches at the anchor state
    tri: np.ndarray             # (T, 3) guard triangles, indices into guard_twists
    points: np.ndarray          # (T, 3) the point each guard triangle keeps clear of
    clearance: np.ndarray       # (T,) its distance at the anchor state, less the slack
    slack: np.ndarray           # (T,) half a segment spacing for ray samples, else 0
    rest: float                 # smallest clearance of any triangle that is no guard
    patch: np.ndarray           # (P, 3) coarse triangles around the exit, into guard_twists
    patch_edge: float           # longest edge of the triangle the ray crossed at the anchor


def _clean(r: CapacityResult) -> bool:
    """A cold answer the warm steps may continue: one crossing, one Newton root, no flag."""
    return (r.status is Status.OK and not r.flags and r.n_hits == 1
            and not any(w in r.detail for w in ('closure', 'dense bracket', 'earlier exit'))
            and r.detail.startswith('coarse crossings 1,'))


class WarmDirect:
    """Warm-started `direct` (scikit-learn style: hyper-parameters here, learned state in
    attributes with a trailing underscore). `solve(problem, phi)` answers one state of a stream.

    n_twists: the cold solve's bracketing sphere (as DirectSurface, default 400).
    guard_triangles: triangles per mesh kept as guards (closest to the origin and the ray).
    clearance_fraction: a guard triangle may close in by this fraction of its clearance.
    max_twist_drift_rad: warm exit twist at most this far from the anchor's (scaled metric).
    max_capacity_change: warm exit distance within this relative change of the anchor's.
    max_jacobian_change: Frobenius change of the residual's derivative on the tangent plane
        from the previous answer's, relative.
    max_phi_change_rad: pull angle at most this far from the anchor's.
    exit_exclusion_rad: coarse triangles with a vertex this close to the exit twist are not
        ray guards (the exit's own motion is followed by Newton and the checks below).
    ring_rad, ring_tol: rings of this radius and half of it around the root, rad: a misfit of
        the linear model that does not shrink like r^2 (Richardson, beyond ring_tol of the
        distance) is a facet switching next to the root, which falls back.
    max_iter: Newton iterations of a warm step.
    seed_check: run the cold solve's own four seeds (the crossed coarse triangle's
        barycentric and vertex twists) with the warm seed in one batched Newton; each must
        reach the warm root (False: the faster warm step that can miss a nearer root).
    seed_iter: Newton iterations of that batch (at least max_iter).
    patience, rest_steps: after `patience` warm attempts in a row that the checks refused
        (a jump or a second sheet keeps sitting next to the root: the state is parked on
        RFT's set-valued closure), the next `rest_steps` steps are cold without building an
        anchor (an anchor costs about as much as the cold solve, and a warm attempt there
        is refused again); 0 patience: always build one. Every answer stays the cold one.
    direct_options: passed to DirectSurface (rtol, fd_step, max_iter, gap_tol).

    Learned state: anchor_ (None until a clean cold solve), twist_ and jac_ (last exit twist,
    scaled unit, and the residual derivative there), n_steps_, n_fallbacks_,
    fallback_reasons_ (Counter), last_warm_ (bool), last_reason_ (why the last step was cold,
    '' when warm).
    """

    method = 'direct'

    def __init__(self, n_twists: int = 400, guard_triangles: int = 12,
                 clearance_fraction: float = 0.5, max_twist_drift_rad: float = 0.1,
                 max_capacity_change: float = 0.2, max_jacobian_change: float = 0.25,
                 max_phi_change_rad: float = 0.02, exit_exclusion_rad: float = 0.35,
                 ring_rad: float = 3e-3, ring_tol: float = 2e-4, max_iter: int = 10,
                 seed_check: bool = True, seed_iter: int = 10, patience: int = 3,
                 rest_steps: int = 8, **direct_options) -> None:
        self.n_twists = int(n_twists)
        self.guard_triangles = int(guard_triangles)
        self.clearance_fraction = float(clearance_fraction)
        self.max_twist_drift_rad = float(max_twist_drift_rad)
        self.max_capacity_change = float(max_capacity_change)
        self.max_jacobian_change = float(max_jacobian_change)
        self.max_phi_change_rad = float(max_phi_change_rad)
        self.exit_exclusion_rad = float(exit_exclusion_rad)
        self.ring_rad, self.ring_tol = float(ring_rad), float(ring_tol)
        self.max_iter = int(max_iter)
        self.seed_check = bool(seed_check)
        self.seed_iter = int(seed_iter)
        self.patience, self.rest_steps = int(patience), int(rest_steps)
        self.direct_options = dict(direct_options)
        self.reset()

    def reset(self) -> WarmDirect:
        """Forget the stream: the next step is cold."""
        self.anchor_: _Anchor | None = None
        self.twist_: np.ndarray | None = None
        self.jac_: np.ndarray | None = None
        self.n_steps_ = 0
        self.n_fallbacks_ = 0
        self.fallback_reasons_: Counter[str] = Counter()
        self.last_warm_ = False
        self.last_reason_ = ''
        self._refused = 0       # warm attempts refused in a row
        self._resting = 0       # cold steps left without an anchor
        self._fit: tuple[GLSProblem, DirectSurface] | None = None
        return self

    def forget(self) -> None:
        """Drop the anchor but keep the counters (the stream went somewhere unanswerable)."""
        self.anchor_ = None
        self.twist_ = None

    @property
    def fallback_rate_(self) -> float:
        return self.n_fallbacks_ / self.n_steps_ if self.n_steps_ else math.nan

    # -- one step -----------------------------------------------------------------------------
    def solve(self, problem: GLSProblem, phi: float) -> CapacityResult:
        """Capacity along d(phi) of the state whose wrench map `problem` describes; the same
        answer as the cold `direct`, warm when the guards allow it."""
        self.n_steps_ += 1
        why = self._why_not_warm(phi)
        if not why:
            r, why = self._warm(problem, float(phi))
            if r is not None:
                self._refused = 0
                self.last_warm_, self.last_reason_ = True, ''
                return r
            self._refused += 1
            if self.patience and self._refused >= self.patience:
                self._refused, self._resting = 0, self.rest_steps
        self.n_fallbacks_ += 1
        self.fallback_reasons_[why] += 1
        self.last_warm_, self.last_reason_ = False, why
        return self._cold(problem, phi)

    def _why_not_warm(self, phi: float) -> str:
        a = self.anchor_
        if a is None:
            return 'resting' if self._resting else 'no_anchor'
        if not math.isfinite(phi) or abs(phi - a.phi) > self.max_phi_change_rad:
            return 'phi_moved'
        return ''

    def _warm(self, problem: GLSProblem, phi: float) -> tuple[CapacityResult | None, str]:
        a = self.anchor_
        assert a is not None and self.twist_ is not None
        sc = problem.scaling

        eval_scaled = scaled_evaluator(problem)

        # Guards: how far the surface moved near the origin and the load ray since the anchor;
        # evaluated in one call (without the seed check, with Newton's first batch).
        n_g = len(a.guard_twists)
        if self.seed_check:   # the batched Newton below starts the warm seed itself
            w_all = eval_scaled(a.guard_twists)
        else:
            batch0, _, _ = fd_batch(self.twist_,
                                     float(self.direct_options.get('fd_step', 1e-7)))
            w_all = eval_scaled(np.concatenate([a.guard_twists, batch0]))
        if not np.all(np.isfinite(w_all)):
            return None, 'non_finite'
        wg = w_all[:n_g]
        # A changed pull angle swings the guarded ray points by up to s |dphi|.
        swing = a.s * abs(phi - a.phi)
        closed, typical = guard_use_loop(wg, a.guard_wrenches, a.tri, a.points, a.slack,
                                          a.clearance, swing)
        # Triangles that are no guards are at least `rest` away: the typical (median) motion
        # of the guard vertices stands for theirs. (Single vertices next to a switching
        # circle jump along the bridged segment as the state moves, so the maximum would
        # measure the jump, not the surface.)
        use = max(float(closed), (float(typical) + swing) / a.rest) / self.clearance_fraction
        if not use <= 1.0:
            return None, 'guard_moved'
        d = problem.load_direction_scaled(phi)
        opts = self.direct_options
        rtol, fd = float(opts.get('rtol', 1e-12)), float(opts.get('fd_step', 1e-7))
        # The cold solve's view around the exit: one crossing of the coarse patch (below: no
        # thin fold in front of the root where its chord is far, no jump triangle longer than
        # the anchor's in front of the root).
        n_c, s_c, f_c, u_c, v_c = ray_hits_loop(wg, a.patch, d)
        if n_c != 1:
            return None, 'second_exit'
        local: tuple | None = None
        seeds_why = ''
        if self.seed_check:
            # The cold solve's own seeds (the crossed coarse triangle's barycentric twist and
            # its three vertex twists) ride in the same batched Newton calls as the warm seed:
            # the cold answer is the smallest root any of them reaches, and where the map has
            # a second sheet or a jump gap near the root one of them can end on a nearer root
            # (or a gap point within gap_tol of the ray) that the warm seed never sees.
            seeds = self._cold_seeds(a.guard_twists[a.patch[f_c]], u_c, v_c)
            ts, ss, res, jacs, convs, _ = newton_batch(
                eval_scaled, d, np.concatenate([self.twist_[None, :], seeds]), rtol, fd,
                max(self.max_iter, self.seed_iter))
            t0, s0, jac0, conv = ts[0], float(ss[0]), jacs[0], bool(convs[0])
            if conv:
                seeds_why = self._seeds_agree(ts[1:], ss[1:], res[1:], convs[1:], t0, s0)
        else:
            t0, s0, _, jac0, conv, local = newton_one(eval_scaled, d, self.twist_, rtol, fd,
                                                      self.max_iter, first=w_all[n_g:])
        if not (conv and s0 > 0.0 and math.isfinite(s0)):
            return None, 'no_convergence'
        if float(np.arccos(np.clip(t0 @ a.twist, -1.0, 1.0))) > self.max_twist_drift_rad:
            return None, 'twist_moved'
        if abs(s0 / a.s - 1.0) > self.max_capacity_change:
            return None, 'capacity_moved'
        if seeds_why:
            return None, seeds_why
        if abs(s0 - float(s_c)) > 0.8 * DIRECT_FOLD_CHECK_RTOL * s0:
            # The cold solve looks for a fold sheet thinner than the coarse mesh here (from
            # 5 %): the same search from the same root; no sheet means the same answer.
            if earlier_exit(eval_scaled, d, t0, s0) is not None:
                return None, 'earlier_exit'
        wf = wg[a.patch[f_c]]
        if float(np.linalg.norm(wf - np.roll(wf, 1, axis=0), axis=1).max()) > 1.5 * a.patch_edge:
            return None, 'jump_in_front'
        # Rings around the root (below); with the seed check the root's local linear model
        # (its forward differences) is evaluated in the same call.
        r1, r2 = self.ring_rad, 0.5 * self.ring_rad
        dirs = np.concatenate([r1 * _RING, r2 * _RING])
        if local is None:
            bt, u, v = fd_batch(t0, fd)
            ring = unit_rows(t0 + dirs[:, :1] * u + dirs[:, 1:] * v)
            wr = eval_scaled(np.concatenate([bt, ring]))
            local = (wr[0], u, v, (wr[1] - wr[0]) / fd, (wr[2] - wr[0]) / fd)
            w_ring = wr[3:]
        else:
            _, u, v, _, _ = local
            ring = unit_rows(t0 + dirs[:, :1] * u + dirs[:, 1:] * v)
            w_ring = None
        # against the previous answer's Jacobian: a facet switching between two messages
        # changes it at once (slow drift over many messages is the twist and capacity checks')
        assert self.jac_ is not None
        g = tangent_jacobian(local, d)
        dj = float(np.linalg.norm(g - self.jac_)) / max(float(np.linalg.norm(self.jac_)),
                                                        1e-300)
        sv = np.linalg.svd(jac0, compute_uv=False)
        if dj > self.max_jacobian_change or not sv[1] >= 1e-6 * sv[0]:
            return None, 'jump_crossed'
        # A facet switching right next to the root leaves a second sheet a hair away from it.
        # Ring points beyond the switch are off the linear model by the jump; that sheet,
        # the tangent plane shifted by the jump, meets the ray at s0 + (jump . n) / (d . n).
        # In front of the root its root can be the first exit (the cold solve's seeds may
        # land there, the warm seed does not); behind it, the root stays the first exit.
        w0, u, v, du, dv = local
        # The cold solve's local closure check around its root (closure.local_exit): the same
        # patches, evaluated with the ring. A patch crossing in front of the root falls back
        # (the cold solve decides whether a closure exit is there), with a looser threshold
        # and barycentric tolerance than the cold cast so that the warm root's ~1e-10 rad
        # offset from the cold one cannot hide a crossing the cold solve sees.
        patches = patch_twists(t0, _CU, _CV) if HAVE_NUMBA else local_patches(t0)
        if w_ring is None:
            wr = eval_scaled(np.concatenate([ring, patches]))
            w_ring, w_patch = wr[:len(ring)], wr[len(ring):]
        else:
            w_patch = eval_scaled(patches)
        off = w_ring - (w0 + dirs[:, :1] * du + dirs[:, 1:] * dv)
        # Richardson: the smooth part of the misfit grows like r^2, a jump does not; with the
        # r^2 term removed, what is left is a jump between the root and the ring.
        k = len(_RING)
        rich = np.linalg.norm((4.0 * off[k:] - off[:k]) / 3.0, axis=1)
        jumps = rich > self.ring_tol * s0
        if np.any(jumps):
            # The sheet beyond the switch may hold a second root, in front of this one or
            # behind it; which root the cold solve's seeds then land on is theirs to decide.
            return None, 'jump_near'
        s_p = ray_hits_loop(w_patch, _FACES_LOCAL_ALL, d, 1e-6)[1]
        if s_p < s0 * (1.0 - 0.5 * LOCAL_RTOL):
            return None, 'local_exit'
        self.twist_, self.jac_ = t0, g
        detail = (f'warm start from the previous exit: guards used {use:.0%} of their '
                  f'allowance; Jacobian singular values {sv[0]:.3g}, {sv[1]:.3g}')
        return CapacityResult.make(phi, Status.OK, self.method, s0 * sc.force_N, t0, sc,
                                   n_hits=1, detail=detail), ''

    @staticmethod
    def _cold_seeds(tv: np.ndarray, u: float, v: float) -> np.ndarray:
        """The cold solve's seeds (4, 3) at the ray's crossing of a coarse triangle with
        vertex twists `tv` (3, 3) and crossing coordinates (u, v) along its two edges: its
        barycentric twist (as raycast.cast_rays weighs it) and its three vertex twists."""
        bary = np.clip(np.array([1.0 - u - v, u, v]), 0.0, 1.0)
        bary /= max(float(bary.sum()), np.finfo(float).tiny)
        return np.concatenate([unit_rows((bary @ tv)[None, :]), tv])

    def _seeds_agree(self, t: np.ndarray, s: np.ndarray, res: np.ndarray, conv: np.ndarray,
                     t0: np.ndarray, s0: float) -> str:
        """'' when every cold seed's Newton run (twists t, distances s, residuals res,
        converged) ended on the warm root (t0, s0), else the fallback reason."""
        gap_tol = float(self.direct_options.get('gap_tol', 2e-3))
        if not np.all(conv):
            # a seed still off the ray: the cold solve's longer run may stall in a jump gap
            # (accepted within gap_tol) or reach another root; only it can say where
            if np.any((res <= gap_tol * np.maximum(np.abs(s), 1e-3)) & (s > 0.0)
                      & (s < s0 * (1.0 - 1e-7))):
                return 'seed_nearer'
            return 'seed_unsettled'
        ang = np.arccos(np.clip(t @ t0, -1.0, 1.0))
        # the cold solve's own tolerances: distinct roots 1e-7 apart, twist spread 1e-4 rad
        if np.any(np.abs(s - s0) > 1e-7 * s0) or np.any(ang > 1e-4):
            return 'seed_other_root'
        return ''

    def _cold(self, problem: GLSProblem, phi: float) -> CapacityResult:
        # The same problem object again (the caller's state has not moved, only the pull
        # angle): its fit is the same, so the last one answers (a fit is deterministic, and a
        # fitted surface answers every angle as a fresh one would).
        if self._fit is not None and self._fit[0] is problem:
            surface = self._fit[1]
        else:
            surface = DirectSurface(self.n_twists, **self.direct_options).fit(problem)
            self._fit = (problem, surface)
        r = surface.capacity(phi)
        self.anchor_, self.twist_ = None, None
        if self._resting:
            self._resting -= 1
        elif _clean(r) and r.slip_twist_scaled is not None:
            self.anchor_ = self._make_anchor(surface, problem, float(phi), r)
            if self.anchor_ is not None:
                self.twist_, self.jac_ = self.anchor_.twist, self.anchor_.jacobian
        return r

    def _make_anchor(self, surface: DirectSurface, problem: GLSProblem, phi: float,
                     r: CapacityResult) -> _Anchor | None:
        assert r.capacity_N is not None and r.slip_twist_scaled is not None
        assert surface.sphere is not None
        sc = problem.scaling
        s = r.capacity_N / sc.force_N
        twist = unit_rows(np.asarray(r.slip_twist_scaled, dtype=float)[None, :])[0]
        d = problem.load_direction_scaled(phi)
        # Clearance of each coarse triangle: to the origin (status), and to the load-ray
        # segment (a new earlier crossing) except near the exit, whose motion Newton and its
        # checks follow. The segment is sampled; half the sample spacing is taken off.
        sphere, ws = surface.sphere, surface._ws
        near_exit = (sphere.twists_scaled[sphere.faces] @ twist).max(axis=1) \
            > math.cos(self.exit_exclusion_rad)
        c_coarse = triangle_clearance(ws, sphere.faces, np.zeros(3))
        p_coarse = np.zeros((len(sphere.faces), 3))
        step = s / (_SEGMENT_POINTS - 1)
        seg = np.arange(1, _SEGMENT_POINTS)[:, None] * step * d[None, :]
        for p, c_seg in zip(seg, triangle_clearances(ws, sphere.faces, seg, ~near_exit)
                            - 0.5 * step):
            closer = c_seg < c_coarse
            c_coarse[closer], p_coarse[closer] = c_seg[closer], p
        meshes = [(sphere.twists_scaled, sphere.faces, c_coarse, p_coarse)]
        if surface.support_samples_ is not None:   # the dense support check decided too
            dense, wsd = surface.support_samples_
            meshes.append((dense.twists_scaled, dense.faces,
                           triangle_clearance(wsd, dense.faces, np.zeros(3)),
                           np.zeros((len(dense.faces), 3))))
        ts_all, tris, pts, clear, rest, base = [], [], [], [], math.inf, 0
        for ts, faces, c, which in meshes:
            k = min(self.guard_triangles, len(faces) - 1)
            order = np.argpartition(c, k)
            guard, others = order[:k], order[k:]
            rest = min(rest, float(c[others].min()))
            idx, local = np.unique(faces[guard].ravel(), return_inverse=True)
            ts_all.append(ts[idx])
            tris.append(base + local.reshape(-1, 3))
            pts.append(which[guard])
            clear.append(c[guard])
            base += len(idx)
        # The coarse triangles around the exit: a warm step casts the ray on them again, as
        # the cold solve would (a second crossing, a chord far from the root, a jump).
        idx, local = np.unique(sphere.faces[near_exit].ravel(), return_inverse=True)
        ts_all.append(sphere.twists_scaled[idx])
        patch = base + local.reshape(-1, 3)
        hits = ray_hits(ws[idx][local.reshape(-1, 3)], d)[1]
        if len(hits) != 1:
            return None
        f0 = sphere.faces[near_exit][hits[0]]
        patch_edge = float(np.linalg.norm(ws[f0] - ws[np.roll(f0, 1)], axis=1).max())
        clearance = np.concatenate(clear)
        points = np.concatenate(pts)
        # the segment samples' clearances had half a spacing taken off; the raw distance is
        # what a warm step measures again
        slack = np.where(np.any(points != 0.0, axis=1), 0.5 * step, 0.0)
        if not (np.all(clearance > 0.0) and rest > 0.0):
            return None
        guard_ts = np.concatenate(ts_all)

        eval_scaled = scaled_evaluator(problem)

        # The Jacobian at the exit: Newton from the exit converges at once and reports it.
        opts = self.direct_options
        lin = newton_one(eval_scaled, d, twist, float(opts.get('rtol', 1e-12)),
                         float(opts.get('fd_step', 1e-7)), 1)[5]
        if not lin:
            return None
        w_guard = eval_scaled(guard_ts)
        return _Anchor(phi=phi, s=s, twist=twist, jacobian=tangent_jacobian(lin, d),
                       guard_twists=guard_ts,
                       guard_wrenches=w_guard, tri=np.concatenate(tris),
                       points=points, clearance=clearance, slack=slack,
                       rest=rest, patch=patch, patch_edge=patch_edge)
