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
from .newton import cross_rows, unit_rows
from .scaling import DiagonalScaling

# Directions of the ring probe around a warm root (unit vectors of the tangent plane).
_RING = np.column_stack([np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)])
# Samples of the load-ray segment (0, s] whose clearance the guards keep.
_SEGMENT_POINTS = 12


def triangle_distances(vertices: np.ndarray, faces: np.ndarray, point: np.ndarray
                       ) -> np.ndarray:
    """Euclidean distance from `point` (3,) to every triangle `faces` (F, 3) of `vertices`."""
    p = np.asarray(point, dtype=float)
    return _distances(*(vertices[faces[:, i]] - p for i in range(3)))


def _distances(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from the origin to the triangles (a, b, c), each (F, 3).

    Closest point on a triangle (Ericson, Real-Time Collision Detection, 2005, sec. 5.1.5):
    the projection on the plane when it falls inside, else the nearest of the three edges.
    """
    n = cross_rows(b - a, c - a)
    nn = np.einsum('ij,ij->i', n, n)
    # barycentric signs of the projected origin: inside when all three sub-areas agree with n
    inside = ((np.einsum('ij,ij->i', cross_rows(a, b), n) >= 0)
              & (np.einsum('ij,ij->i', cross_rows(b, c), n) >= 0)
              & (np.einsum('ij,ij->i', cross_rows(c, a), n) >= 0) & (nn > 0))
    plane = np.abs(np.einsum('ij,ij->i', n, a)) / np.sqrt(np.maximum(nn, 1e-300))

    def seg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        e = v - u
        t = np.clip(-np.einsum('ij,ij->i', u, e) / np.maximum(np.einsum('ij,ij->i', e, e),
                                                              1e-300), 0.0, 1.0)
        return np.linalg.norm(u + t[:, None] * e, axis=1)

    edge = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return np.where(inside, plane, edge)


def _fd_batch(t: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The twist, its two forward-difference neighbours (as newton._tangent_basis), u, v."""
    k = int(np.argmin(np.abs(t)))
    helper = np.zeros(3)
    helper[k] = 1.0
    u = np.array([t[1] * helper[2] - t[2] * helper[1], t[2] * helper[0] - t[0] * helper[2],
                  t[0] * helper[1] - t[1] * helper[0]])
    u /= math.sqrt(u @ u)
    v = np.array([t[1] * u[2] - t[2] * u[1], t[2] * u[0] - t[0] * u[2],
                  t[0] * u[1] - t[1] * u[0]])
    batch = np.stack([t, t + h * u, t + h * v])
    batch[1:] /= np.linalg.norm(batch[1:], axis=1, keepdims=True)
    return batch, u, v


def _ray_hits(tri: np.ndarray, d: np.ndarray, bary_tol: float = 1e-9,
              dist_rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """raycast.all_hits for a few triangles (T, 3, 3) and a ray from the origin: the sorted
    distinct crossing distances and their triangles (same tolerances, less overhead)."""
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n_det = cross_rows(e2, e1)
    det = n_det @ d
    det_tol = 1e-12 * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    ok = np.abs(det) > det_tol
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    q0 = -v0
    q = cross_rows(q0, e1)
    u = (cross_rows(e2, q0) @ d) * inv
    v = (q @ d) * inv
    s = np.einsum('ij,ij->i', e2, q) * inv
    hit = ok & (u >= -bary_tol) & (v >= -bary_tol) & (u + v <= 1.0 + bary_tol) & (s > 0.0)
    idx = np.flatnonzero(hit)
    order = idx[np.argsort(s[idx])]
    ss = s[order]
    keep = np.ones(len(order), dtype=bool)
    keep[1:] = np.diff(ss) > dist_rtol * max(float(np.abs(tri).max()), 1e-300)
    return ss[keep], order[keep]


def newton_one(eval_scaled, d: np.ndarray, seed: np.ndarray, rtol: float = 1e-12,
               fd_step: float = 1e-7, max_iter: int = 10, first: np.ndarray | None = None
               ) -> tuple[np.ndarray, float, float, np.ndarray, bool, tuple]:
    """`newton.newton_on_sphere` for one seed, with the same steps, tolerance, trust region
    and backtracking, written for a single 3-vector (the batched version's array overhead is
    most of a warm step). `first`: the wrenches of the seed's first batch (_fd_batch), when the
    caller evaluated them already. Returns (twist, s, residual, jacobian (2, 2), converged,
    local) with local = (W(t), u, v, dW/du, dW/dv) at that twist (the local linear model)."""
    e1 = np.array([-d[1], d[0], 0.0])
    t = seed / np.linalg.norm(seed)
    best_t, best_r, best_s = t, math.inf, 0.0
    best_step = np.zeros(2)
    bu = bv = np.zeros(3)
    jac = np.zeros((2, 2))
    local: tuple = ()
    lam = 1.0
    for it in range(max_iter):
        batch, u, v = _fd_batch(t, fd_step)
        w = first if (it == 0 and first is not None) else eval_scaled(batch)
        r = np.array([e1 @ w[0], w[0, 2]])
        rn = math.hypot(r[0], r[1])
        dw1, dw2 = w[1] - w[0], w[2] - w[0]
        j_now = np.array([[e1 @ dw1, e1 @ dw2], [dw1[2], dw2[2]]]) / fd_step
        improved = rn < best_r
        if improved:
            best_t, best_r, best_s, jac = t, rn, float(d @ w[0]), j_now
            local = (w[0], u, v, dw1 / fd_step, dw2 / fd_step)
        if best_r <= rtol * max(abs(best_s), 1e-3):
            return best_t, best_s, best_r, jac, True, local
        if improved:
            det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
            if det != 0.0:
                step = -np.array([jac[1, 1] * r[0] - jac[0, 1] * r[1],
                                  -jac[1, 0] * r[0] + jac[0, 0] * r[1]]) / det
            else:
                step = -np.linalg.pinv(jac) @ r
            nrm = math.hypot(step[0], step[1])
            step *= min(1.0, 0.3 / max(nrm, 1e-300))   # trust region, rad
            best_step, bu, bv, lam = step, u, v, 1.0
        else:
            lam *= 0.5
            if lam < 1e-6:
                break
        t = best_t + lam * (best_step[0] * bu + best_step[1] * bv)
        t = t / math.sqrt(t @ t)
    return best_t, best_s, best_r, jac, False, local


def newton_batch(eval_scaled, d: np.ndarray, seeds: np.ndarray, rtol: float = 1e-12,
                 fd_step: float = 1e-7, max_iter: int = 40):
    """`newton.newton_on_sphere` (same steps, tolerance, trust region, backtracking and
    returns) for a handful of seeds, each iteration's arithmetic in two scalar kernels
    (_newton_batch_twists, _newton_update): numpy's per-call overhead on five seeds cost
    more than the wrench calls themselves. The cold solve keeps the reference version; a
    test holds the two equal."""
    d = np.ascontiguousarray(d, dtype=float)
    t = np.ascontiguousarray(unit_rows(np.asarray(seeds, dtype=float)))
    k = len(t)
    best_t = t.copy()
    best_r = np.full(k, np.inf)
    best_step = np.zeros((k, 2))
    bu, bv = np.zeros((k, 3)), np.zeros((k, 3))
    lam = np.ones(k)
    jac = np.zeros((k, 2, 2))
    s = np.zeros(k)
    conv = np.zeros(k, dtype=np.bool_)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        batch, u, v = _newton_batch_twists(t, fd_step)
        w = np.ascontiguousarray(eval_scaled(batch), dtype=float)
        if _newton_update(t, u, v, w, d, fd_step, rtol, best_t, best_r, best_step, bu, bv,
                          lam, jac, s, conv):
            break
    return best_t, s, best_r, jac, conv, it


def _tangent_jacobian(local: tuple, d: np.ndarray) -> np.ndarray:
    """The residual's derivative on the sphere's tangent plane as a (2, 3) map of twist
    increments: independent of the (u, v) basis, which Newton picks per twist and which
    swaps where the twist's smallest component changes."""
    _, u, v, du, dv = local
    proj = np.array([[-d[1], d[0], 0.0], [0.0, 0.0, 1.0]])
    return np.outer(proj @ du, u) + np.outer(proj @ dv, v)


@dataclass(frozen=True)
class _Anchor:
    """What a clean cold solve leaves for the warm steps after it (scaled spaces)."""

    phi: float
    s: float                    # exit distance along d
    twist: np.ndarray           # (3,) exit twist, unit
    jacobian: np.ndarray        # (2, 3) residual derivative at the exit (_tangent_jacobian)
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
                 seed_check: bool = True, seed_iter: int = 10, **direct_options) -> None:
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
                self.last_warm_, self.last_reason_ = True, ''
                return r
        self.n_fallbacks_ += 1
        self.fallback_reasons_[why] += 1
        self.last_warm_, self.last_reason_ = False, why
        return self._cold(problem, phi)

    def _why_not_warm(self, phi: float) -> str:
        a = self.anchor_
        if a is None:
            return 'no_anchor'
        if not math.isfinite(phi) or abs(phi - a.phi) > self.max_phi_change_rad:
            return 'phi_moved'
        return ''

    def _warm(self, problem: GLSProblem, phi: float) -> tuple[CapacityResult | None, str]:
        a = self.anchor_
        assert a is not None and self.twist_ is not None
        sc = problem.scaling

        eval_scaled = _scaled_evaluator(problem)

        # Guards: how far the surface moved near the origin and the load ray since the anchor;
        # evaluated in one call (without the seed check, with Newton's first batch).
        n_g = len(a.guard_twists)
        if self.seed_check:   # the batched Newton below starts the warm seed itself
            w_all = eval_scaled(a.guard_twists)
        else:
            batch0, _, _ = _fd_batch(self.twist_,
                                     float(self.direct_options.get('fd_step', 1e-7)))
            w_all = eval_scaled(np.concatenate([a.guard_twists, batch0]))
        if not np.all(np.isfinite(w_all)):
            return None, 'non_finite'
        wg = w_all[:n_g]
        # A changed pull angle swings the guarded ray points by up to s |dphi|.
        swing = a.s * abs(phi - a.phi)
        closed, typical = _guard_use_loop(wg, a.guard_wrenches, a.tri, a.points, a.slack,
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
        n_c, s_c, f_c, u_c, v_c = _ray_hits_loop(wg, a.patch, d)
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
            bt, u, v = _fd_batch(t0, fd)
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
        g = _tangent_jacobian(local, d)
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
        patches = _patch_twists(t0, _CU, _CV) if numba is not None else local_patches(t0)
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
        s_p = _ray_hits_loop(w_patch, _FACES_LOCAL_ALL, d, 1e-6)[1]
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
        surface = DirectSurface(self.n_twists, **self.direct_options).fit(problem)
        r = surface.capacity(phi)
        self.anchor_, self.twist_ = None, None
        if _clean(r) and r.slip_twist_scaled is not None:
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
        c_coarse = _clearance(ws, sphere.faces, np.zeros(3))
        p_coarse = np.zeros((len(sphere.faces), 3))
        step = s / (_SEGMENT_POINTS - 1)
        for p in np.arange(1, _SEGMENT_POINTS)[:, None] * step * d[None, :]:
            c_seg = _clearance(ws, sphere.faces, p, ~near_exit) - 0.5 * step
            closer = c_seg < c_coarse
            c_coarse[closer], p_coarse[closer] = c_seg[closer], p
        meshes = [(sphere.twists_scaled, sphere.faces, c_coarse, p_coarse)]
        if surface.support_samples_ is not None:   # the dense support check decided too
            dense, wsd = surface.support_samples_
            meshes.append((dense.twists_scaled, dense.faces,
                           _clearance(wsd, dense.faces, np.zeros(3)),
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
        hits = _ray_hits(ws[idx][local.reshape(-1, 3)], d)[1]
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

        eval_scaled = _scaled_evaluator(problem)

        # The Jacobian at the exit: Newton from the exit converges at once and reports it.
        opts = self.direct_options
        lin = newton_one(eval_scaled, d, twist, float(opts.get('rtol', 1e-12)),
                         float(opts.get('fd_step', 1e-7)), 1)[5]
        if not lin:
            return None
        w_guard = eval_scaled(guard_ts)
        return _Anchor(phi=phi, s=s, twist=twist, jacobian=_tangent_jacobian(lin, d),
                       guard_twists=guard_ts,
                       guard_wrenches=w_guard, tri=np.concatenate(tris),
                       points=points, clearance=clearance, slack=slack,
                       rest=rest, patch=patch, patch_edge=patch_edge)


def _scaled_evaluator(problem: GLSProblem):
    """Scaled unit twists (M, 3) -> scaled wrenches, as
    sc.wrench_to_scaled(problem.wrenches(sc.twist_from_scaled(ts))) computes them (bitwise:
    the same divisions, sums and square root), with the scaling's diagonal taken once and the
    twists' normalisation in one small kernel (numpy's took ~5 us of a few-twist call)."""
    sc = problem.scaling
    plain = (isinstance(sc, DiagonalScaling)
             and type(sc).twist_from_scaled is DiagonalScaling.twist_from_scaled
             and type(sc).wrench_to_scaled is DiagonalScaling.wrench_to_scaled)
    if not plain or numba is None:
        return lambda ts: sc.wrench_to_scaled(problem.wrenches(sc.twist_from_scaled(ts)))
    diag = np.array(sc.diag, dtype=float)

    def eval_scaled(ts: np.ndarray) -> np.ndarray:
        return problem.wrenches(_unit_rows_over(np.asarray(ts, dtype=float), diag)) / diag
    return eval_scaled


def _clearance(ws: np.ndarray, faces: np.ndarray, point: np.ndarray,
               mask: np.ndarray | None = None) -> np.ndarray:
    """Distance of every triangle to `point`; only triangles that can be close are measured
    exactly (inf elsewhere, and where `mask` is False): a triangle is no closer than its
    nearest vertex minus 0.58 of its longest edge (every point of a triangle lies within
    L / sqrt(3) of some vertex)."""
    v = ws - point
    upper = np.linalg.norm(v, axis=1)[faces].min(axis=1)
    edge = np.linalg.norm(ws[faces] - ws[np.roll(faces, 1, axis=1)], axis=2).max(axis=1)
    lower = upper - edge / math.sqrt(3.0)
    ok = np.ones(len(faces), dtype=bool) if mask is None else mask
    if not np.any(ok):
        return np.full(len(faces), np.inf)
    # enough candidates to know the few closest and a bound on all others
    bound = np.partition(upper[ok], min(64, int(ok.sum()) - 1))[min(64, int(ok.sum()) - 1)]
    cand = np.flatnonzero(ok & (lower <= bound))
    out = np.where(ok, np.maximum(lower, 0.0), np.inf)
    out[cand] = triangle_distances(ws, faces[cand], point)
    return out


# -- small scalar kernels of a warm step (numba when installed; the numpy versions above are the
# reference and the fallback). A warm step handles a few dozen triangles, where numpy's
# per-call overhead is most of the time.
try:
    import numba
except ImportError:  # pragma: no cover - machines without numba use the numpy versions
    numba = None  # type: ignore[assignment]


def _unit_rows_over(ts, diag):
    """newton.unit_rows(ts / diag) for ts (M, 3): the same operations in the same order."""
    out = np.empty_like(ts)
    for i in range(ts.shape[0]):
        x0, x1, x2 = ts[i, 0] / diag[0], ts[i, 1] / diag[1], ts[i, 2] / diag[2]
        n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not n > 0.0:
            n = 1.0
        out[i, 0], out[i, 1], out[i, 2] = x0 / n, x1 / n, x2 / n
    return out


def _point_triangle(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Distance from the origin to the triangle (a, b, c), as _distances does it."""
    e1x, e1y, e1z = bx - ax, by - ay, bz - az
    e2x, e2y, e2z = cx - ax, cy - ay, cz - az
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    nn = nx * nx + ny * ny + nz * nz
    s1 = (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz
    s2 = (by * cz - bz * cy) * nx + (bz * cx - bx * cz) * ny + (bx * cy - by * cx) * nz
    s3 = (cy * az - cz * ay) * nx + (cz * ax - cx * az) * ny + (cx * ay - cy * ax) * nz
    if s1 >= 0.0 and s2 >= 0.0 and s3 >= 0.0 and nn > 0.0:
        return abs(nx * ax + ny * ay + nz * az) / math.sqrt(nn)
    best = math.inf
    for ux, uy, uz, vx, vy, vz in ((ax, ay, az, bx, by, bz), (bx, by, bz, cx, cy, cz),
                                   (cx, cy, cz, ax, ay, az)):
        ex, ey, ez = vx - ux, vy - uy, vz - uz
        ee = max(ex * ex + ey * ey + ez * ez, 1e-300)
        t = min(max(-(ux * ex + uy * ey + uz * ez) / ee, 0.0), 1.0)
        px, py, pz = ux + t * ex, uy + t * ey, uz + t * ez
        best = min(best, math.sqrt(px * px + py * py + pz * pz))
    return best


def _guard_use_loop(wg, w0, tri, points, slack, clearance, swing):
    """(largest closed-in fraction of a guard triangle's clearance, median guard motion)."""
    closed = -math.inf
    for k in range(tri.shape[0]):
        i, j, m = tri[k, 0], tri[k, 1], tri[k, 2]
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        dist = _point_triangle(wg[i, 0] - px, wg[i, 1] - py, wg[i, 2] - pz,
                               wg[j, 0] - px, wg[j, 1] - py, wg[j, 2] - pz,
                               wg[m, 0] - px, wg[m, 1] - py, wg[m, 2] - pz)
        closed = max(closed, (clearance[k] - (dist - slack[k] - swing)) / clearance[k])
    motion = np.empty(wg.shape[0])
    for k in range(wg.shape[0]):
        dx, dy, dz = wg[k, 0] - w0[k, 0], wg[k, 1] - w0[k, 1], wg[k, 2] - w0[k, 2]
        motion[k] = math.sqrt(dx * dx + dy * dy + dz * dz)
    return closed, np.median(motion)


def _ray_hits_loop(wg, patch, d, bary_tol=1e-9, dist_rtol=1e-9):
    """_ray_hits on the triangles `patch` of `wg`: (distinct crossings, first s, its face,
    and the crossing's coordinates u, v along the face's edges to its second and third
    vertex, as raycast's)."""
    n = patch.shape[0]
    s_all = np.empty(n)
    u_all = np.empty(n)
    v_all = np.empty(n)
    face = np.empty(n, dtype=np.int64)
    h = 0
    scale = 0.0
    for k in range(n):
        for c in range(3):
            for q in range(3):
                scale = max(scale, abs(wg[patch[k, c], q]))
    dx, dy, dz = d[0], d[1], d[2]
    for k in range(n):
        a, b, c = patch[k, 0], patch[k, 1], patch[k, 2]
        v0x, v0y, v0z = wg[a, 0], wg[a, 1], wg[a, 2]
        e1x, e1y, e1z = wg[b, 0] - v0x, wg[b, 1] - v0y, wg[b, 2] - v0z
        e2x, e2y, e2z = wg[c, 0] - v0x, wg[c, 1] - v0y, wg[c, 2] - v0z
        # n_det = e2 x e1, det = n_det . d
        det = (e2y * e1z - e2z * e1y) * dx + (e2z * e1x - e2x * e1z) * dy \
            + (e2x * e1y - e2y * e1x) * dz
        tol = 1e-12 * math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z) \
            * math.sqrt(e2x * e2x + e2y * e2y + e2z * e2z)
        if not abs(det) > tol:
            continue
        inv = 1.0 / det
        q0x, q0y, q0z = -v0x, -v0y, -v0z
        u = ((e2y * q0z - e2z * q0y) * dx + (e2z * q0x - e2x * q0z) * dy
             + (e2x * q0y - e2y * q0x) * dz) * inv
        qx, qy, qz = q0y * e1z - q0z * e1y, q0z * e1x - q0x * e1z, q0x * e1y - q0y * e1x
        v = (qx * dx + qy * dy + qz * dz) * inv
        s = (e2x * qx + e2y * qy + e2z * qz) * inv
        if u >= -bary_tol and v >= -bary_tol and u + v <= 1.0 + bary_tol and s > 0.0:
            s_all[h], u_all[h], v_all[h] = s, u, v
            face[h] = k
            h += 1
    if h == 0:
        return 0, math.inf, -1, math.nan, math.nan
    order = np.argsort(s_all[:h])
    count = 1
    for i in range(1, h):
        if s_all[order[i]] - s_all[order[i - 1]] > dist_rtol * max(scale, 1e-300):
            count += 1
    i = order[0]
    return count, s_all[i], face[i], u_all[i], v_all[i]


def _patch_twists(t, cu, cv):
    """closure.local_patches(t) for a unit twist t (3,): the twists t + cu u + cv v, unit,
    with (u, v) the tangent basis of newton._tangent_basis (the same operations per row;
    numpy's 3-vector calls cost more than the 243 rows)."""
    n = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
    tx, ty, tz = t[0] / n, t[1] / n, t[2] / n
    m = 0   # first smallest |component|, as np.argmin
    if abs(ty) < abs(tx):
        m = 1
    if abs(tz) < (abs(ty) if m == 1 else abs(tx)):
        m = 2
    hx, hy, hz = (1.0, 0.0, 0.0) if m == 0 else ((0.0, 1.0, 0.0) if m == 1 else (0.0, 0.0, 1.0))
    ux, uy, uz = ty * hz - tz * hy, tz * hx - tx * hz, tx * hy - ty * hx
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / n, uy / n, uz / n
    vx, vy, vz = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux
    out = np.empty((cu.shape[0], 3))
    for i in range(cu.shape[0]):
        px = tx + cu[i] * ux + cv[i] * vx
        py = ty + cu[i] * uy + cv[i] * vy
        pz = tz + cu[i] * uz + cv[i] * vz
        n = math.sqrt(px * px + py * py + pz * pz)
        out[i, 0], out[i, 1], out[i, 2] = px / n, py / n, pz / n
    return out


def _newton_batch_twists(t, h):
    """The twists of one Newton iteration (newton_on_sphere's batch: the points, then their
    forward differences along u, then along v) and the tangent bases (u, v)."""
    k = t.shape[0]
    u = np.empty((k, 3))
    v = np.empty((k, 3))
    batch = np.empty((3 * k, 3))
    for i in range(k):
        tx, ty, tz = t[i, 0], t[i, 1], t[i, 2]
        m = 0   # first smallest |component|, as np.argmin
        if abs(ty) < abs(tx):
            m = 1
        if abs(tz) < (abs(ty) if m == 1 else abs(tx)):
            m = 2
        hx, hy, hz = (1.0, 0.0, 0.0) if m == 0 else ((0.0, 1.0, 0.0) if m == 1
                                                       else (0.0, 0.0, 1.0))
        ux, uy, uz = ty * hz - tz * hy, tz * hx - tx * hz, tx * hy - ty * hx
        n = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / n, uy / n, uz / n
        vx, vy, vz = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux
        u[i, 0], u[i, 1], u[i, 2] = ux, uy, uz
        v[i, 0], v[i, 1], v[i, 2] = vx, vy, vz
        batch[i, 0], batch[i, 1], batch[i, 2] = tx, ty, tz
        for j, (ex, ey, ez) in enumerate(((ux, uy, uz), (vx, vy, vz))):
            px, py, pz = tx + h * ex, ty + h * ey, tz + h * ez
            n = math.sqrt(px * px + py * py + pz * pz)
            row = (j + 1) * k + i
            batch[row, 0], batch[row, 1], batch[row, 2] = px / n, py / n, pz / n
    return batch, u, v


def _newton_update(t, u, v, w, d, h, rtol, best_t, best_r, best_step, bu, bv, lam, jac, s,
                   conv):
    """One newton_on_sphere iteration after its wrench call, in place; the next twists go
    into t. True when every seed converged or gave up (the reference's two breaks)."""
    k = t.shape[0]
    e1x, e1y = -d[1], d[0]
    r0 = np.empty(k)
    r1 = np.empty(k)
    improved = np.zeros(k, dtype=np.bool_)
    all_conv = True
    for i in range(k):
        w0x, w0y, w0z = w[i, 0], w[i, 1], w[i, 2]
        ra, rb = e1x * w0x + e1y * w0y, w0z
        r0[i], r1[i] = ra, rb
        rn = math.sqrt(ra * ra + rb * rb)
        if rn < best_r[i]:
            improved[i] = True
            best_r[i] = rn
            best_t[i, 0], best_t[i, 1], best_t[i, 2] = t[i, 0], t[i, 1], t[i, 2]
            a1 = (w[k + i, 0] - w0x, w[k + i, 1] - w0y, w[k + i, 2] - w0z)
            a2 = (w[2 * k + i, 0] - w0x, w[2 * k + i, 1] - w0y, w[2 * k + i, 2] - w0z)
            jac[i, 0, 0] = (e1x * a1[0] + e1y * a1[1]) / h
            jac[i, 1, 0] = a1[2] / h
            jac[i, 0, 1] = (e1x * a2[0] + e1y * a2[1]) / h
            jac[i, 1, 1] = a2[2] / h
            s[i] = d[0] * w0x + d[1] * w0y + d[2] * w0z
        conv[i] = best_r[i] <= rtol * max(abs(s[i]), 1e-3)
        if not conv[i]:
            all_conv = False
    if all_conv:
        return True
    done = True
    for i in range(k):
        if conv[i]:
            t[i, 0], t[i, 1], t[i, 2] = best_t[i, 0], best_t[i, 1], best_t[i, 2]
            continue
        if improved[i]:
            j00, j01, j10, j11 = jac[i, 0, 0], jac[i, 0, 1], jac[i, 1, 0], jac[i, 1, 1]
            det = j00 * j11 - j01 * j10
            if det != 0.0:
                sa = -(j11 * r0[i] - j01 * r1[i]) / det
                sb = -(-j10 * r0[i] + j00 * r1[i]) / det
            else:
                # rank <= 1: the pseudo-inverse is J^T / |J|_F^2 (0 for J = 0)
                f2 = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
                f2 = f2 if f2 > 0.0 else math.inf
                sa = -(j00 * r0[i] + j10 * r1[i]) / f2
                sb = -(j01 * r0[i] + j11 * r1[i]) / f2
            nrm = math.sqrt(sa * sa + sb * sb)
            sc = min(1.0, 0.3 / max(nrm, 1e-300))    # trust region, rad
            best_step[i, 0], best_step[i, 1] = sa * sc, sb * sc
            for c in range(3):
                bu[i, c], bv[i, c] = u[i, c], v[i, c]
            lam[i] = 1.0
        else:
            lam[i] *= 0.5
        fa, fb = lam[i] * best_step[i, 0], lam[i] * best_step[i, 1]
        px = best_t[i, 0] + fa * bu[i, 0] + fb * bv[i, 0]
        py = best_t[i, 1] + fa * bu[i, 1] + fb * bv[i, 1]
        pz = best_t[i, 2] + fa * bu[i, 2] + fb * bv[i, 2]
        n = math.sqrt(px * px + py * py + pz * pz)
        t[i, 0], t[i, 1], t[i, 2] = px / n, py / n, pz / n
        if not lam[i] < 1e-6:
            done = False
    return done


if numba is not None:
    _jit = numba.njit(cache=True, nogil=True)
    _point_triangle = _jit(_point_triangle)
    _guard_use_loop = _jit(_guard_use_loop)
    _ray_hits_loop = _jit(_ray_hits_loop)
    _newton_batch_twists = _jit(_newton_batch_twists)
    _patch_twists = _jit(_patch_twists)
    _newton_update = _jit(_newton_update)
    _unit_rows_over = _jit(_unit_rows_over)
