"""The full 6D path: limit surface over 6D twists, capacity along a 6D load ray, 6D slip twist.

Used when a posed anchor is not mirror-symmetric about the pull plane (a yawed tether, an asymmetric
body), where the sagittal reduction of surfaces/ (3D wrench space) would be wrong
(docs/design/six-d.md). Spaces (world axes, reference point = the tether point p):

    wrench W = (Fx, Fy, Fz, Mx, My, Mz) in N, N m;  twist t = (vx, vy, vz, wx, wy, wz) in m/s, rad/s
    W_ext(t) = -W_rft(t) - W_gravity  (the load the tether must apply to move the body along t)

Scaled metric, as in surfaces/scaling.py: Ws = W / S, ts = S t / |S t|, S = diag(s_F x3,
s_F L_c x3), so the power pairing t . W is kept and one force scale keeps pull directions.

A 5-sphere of twists cannot be triangulated and ray-cast cheaply, so this is the `direct`
method in 6D: no surface is stored.

1. Fit: W_ext on n quasi-uniform unit twists of S^5 (a fixed-seed sample, default 2,000) in
   one batched call: the bracketing cloud.
2. Support (is the weight held?): the origin of W_ext space is inside the surface when the
   weight lies inside the gravity-free surface W_0(t) = -W_rft(t). Cast the ray of W_0 along
   the gravity wrench's direction; held when |W_g| is below its first exit.
3. Query: a twist is on the load ray o + s d when the five residuals P (Ws(t) - o) vanish
   (P an orthonormal basis of d's complement), s = d . (Ws(t) - o) > 0. The cloud twists whose
   wrench lies closest in angle to the ray seed a batched Newton solve on S^5 (5 unknowns,
   forward differences: 6 twists per seed per iteration); the capacity is the smallest
   positive root (the first exit as the load ramps up from zero).
4. Candidates free Newton cannot reach (docs/design/six-d.md, "Folded surfaces"): seeds that
   stalled short of the first converged root try the switching set (a plate sliding edge-on);
   extra seeds (a mirror plane's in-plane slip) start a patch search on the closure; and a
   checked in-plane answer (`InPlane6`) of a posed anchor symmetric about the pull plane is kept
   unless the search finds an exact root before it.

Limits: a crossing none of the seeds reaches is missed (raise n_twists / n_seeds); where the
ray passes through a jump of the RFT map (a facet switching between leading and trailing) no
twist maps onto it exactly: a miss below `gap_tol` of the distance is accepted with the flag
`on_jump` (capacity that precise), a larger one is DEGENERATE `no_root`.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .surfaces.newton import damped_newton_step, unit_rows
from .surfaces.scaling import DiagonalScaling
from .types import Status

WrenchFn6 = Callable[[np.ndarray], np.ndarray]

DEFAULT_TWISTS_6D = 2000
DEFAULT_SEEDS_6D = 12
EARLIER_ANGLE = 0.5   # rad: cloud wrenches this close to the ray seed the earlier-crossing search
EARLIER_ROUNDS = 4    # rounds of that search (each only while it finds candidates)
SETTLED_RTOL = 1e-4   # closure patch: relative spread of the last distances accepted
IN_PLANE_RTOL = 1e-8  # a lifted in-plane root must map onto the 6D ray this closely (relative)
STALLED_TRIES = 3     # stalled seeds (short of the first converged root) tried on a switching set


@dataclass(frozen=True)
class Scaling6(DiagonalScaling):
    """Force scale s_F (N) and length L_c (m) of the scaled 6D spaces (see module doc)."""

    @property
    def diag(self) -> np.ndarray:
        f, lc = self.force_N, self.length_m
        return np.array([f, f, f, f * lc, f * lc, f * lc])


@lru_cache(maxsize=8)
def sphere5(n: int) -> np.ndarray:
    """n unit vectors of R^6, quasi-uniform on S^5: a fixed-seed Gaussian sample, normalised,
    its antipodes included (every cloud then has both senses of each motion). Read-only."""
    half = (int(n) + 1) // 2
    g = np.random.default_rng(20230517).normal(size=(half, 6))
    pts = unit_rows(np.concatenate([g, -g])[: int(n)])
    pts.setflags(write=False)
    return pts


@dataclass(frozen=True)
class Problem6:
    """wrench_fn: raw twists (M, 6) -> W_ext (M, 6) about p, N and N m (vectorised, rate
    independent). gravity: the gravity wrench W_g (6,) about p. scaling: the 6D metric."""

    wrench_fn: WrenchFn6
    gravity: np.ndarray
    scaling: Scaling6
    switch_forms: np.ndarray | None = None

    # switch_forms: (F, 6) a_j = (n_j, r_j x n_j) of the buried facets (r_j from p): facet j
    # switches between trailing and leading where a_j . t = 0 (n . (v + w x r) = 0), linear
    # in the twist. Lets the solver land exactly on a switching set (see `_on_switching_set`).


@dataclass(frozen=True)
class InPlane6:
    """The sagittal answer lifted into 6D: capacity_N (N), the slip twist as a 6D scaled
    twist (vx, vy, vz, wx L_c, wy L_c, wz L_c) (any norm), its flags, and the unit normal
    (3,) of the pull plane (world): in-plane wrenches have F . n = 0 and M along n."""

    capacity_N: float
    twist_scaled: tuple[float, ...]
    flags: tuple[str, ...]
    plane_normal: tuple[float, float, float]


@dataclass(frozen=True)
class Result6:
    """Capacity along a 6D load direction and the 6D slip twist at the first exit.

    capacity_N: tether force at the first exit, N; None unless status.has_value.
    slip_twist: the slip twist (vx, vy, vz, wx, wy, wz) of the tether point, world axes, m/s and
    rad/s, unit Euclidean norm; slip_twist_scaled: the same direction as a unit vector
    (vx, vy, vz, wx L_c, wy L_c, wz L_c). Both None without a value.
    """

    status: Status
    capacity_N: float | None = None
    slip_twist: tuple[float, ...] | None = None
    slip_twist_scaled: tuple[float, ...] | None = None
    n_hits: int = -1
    reason: str = ''
    detail: str = ''
    flags: tuple[str, ...] = ()
    unchecked_capacity_N: float | None = None
    method: str = 'direct-6d'

    @property
    def ok(self) -> bool:
        return self.status.has_value


def _householder_bases(t: np.ndarray) -> np.ndarray:
    """(K, 5, 6) orthonormal bases of the tangent spaces of unit vectors t (K, 6).

    The Householder reflection H that maps e_j to t (j = the largest component) is orthogonal
    and symmetric; its other columns span the complement of t."""
    k, dim = t.shape
    j = np.argmax(np.abs(t), axis=1)
    sgn = np.where(t[np.arange(k), j] >= 0.0, 1.0, -1.0)
    u = t.copy()
    u[np.arange(k), j] -= sgn
    u = unit_rows(u)
    h = np.eye(dim)[None] - 2.0 * u[:, :, None] * u[:, None, :]
    keep = np.ones((k, dim), dtype=bool)
    keep[np.arange(k), j] = False
    return h.transpose(0, 2, 1)[keep].reshape(k, dim - 1, dim)


def complement_basis(d: np.ndarray) -> np.ndarray:
    """(5, 6) orthonormal rows spanning the complement of the unit vector d."""
    return _householder_bases(np.asarray(d, dtype=float).reshape(1, -1))[0]


def newton_on_sphere6(eval_scaled: Callable[[np.ndarray], np.ndarray], origin: np.ndarray,
                      d: np.ndarray, seeds: np.ndarray, rtol: float = 1e-12,
                      fd_step: float = 1e-7, max_iter: int = 40):
    """Twists t on S^5 with eval_scaled(t) - origin along d, from seeds (K, 6).

    All seeds advance together: one eval_scaled call of 6K twists per iteration (the point and
    five forward differences). Steps that do not reduce the residual are halved.
    Returns (t, s, residual, converged, iterations) per seed.
    """
    proj = complement_basis(d)                           # (5, 6)
    k = len(seeds)
    t = unit_rows(np.asarray(seeds, dtype=float))
    best_t, best_r, s = t.copy(), np.full(k, np.inf), np.zeros(k)
    best_step = np.zeros((k, 5))
    best_basis = np.zeros((k, 5, 6))
    lam = np.ones(k)
    conv = np.zeros(k, dtype=bool)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 (returned)
        basis = _householder_bases(t)                    # (k, 5, 6)
        probe = unit_rows(t[:, None, :] + fd_step * basis)   # (k, 5, 6)
        batch = np.concatenate([t, probe.reshape(-1, 6)])
        w = eval_scaled(batch) - origin
        w0, wp = w[:k], w[k:].reshape(k, 5, 6)
        r = w0 @ proj.T                                  # (k, 5)
        rn = np.linalg.norm(r, axis=1)
        jac = np.einsum('kij,lj->kli', wp - w0[:, None, :], proj) / fd_step   # (k, 5 res, 5 dir)
        improved = rn < best_r
        best_r = np.where(improved, rn, best_r)
        best_t[improved] = t[improved]
        s[improved] = (w0 @ d)[improved]
        conv = best_r <= rtol * np.maximum(np.abs(s), 1e-3)
        if np.all(conv):
            break
        fresh = improved & ~conv
        if np.any(fresh):
            step = damped_newton_step(jac[fresh], r[fresh])
            best_step[fresh] = step
            best_basis[fresh] = basis[fresh]
            lam[fresh] = 1.0
        lam[~improved & ~conv] *= 0.5
        nxt = unit_rows(best_t + np.einsum('k,ki,kij->kj', lam, best_step, best_basis))
        t = np.where(conv[:, None], best_t, nxt)
        if np.all(conv | (lam < 1e-6)):
            break
    return best_t, s, best_r, conv, it


@dataclass
class Surface6:
    """The 6D `direct` method: fit (cloud + support check), then `capacity(d)` per direction.

    n_twists: bracketing cloud on S^5. n_seeds: Newton seeds per query (the cloud twists
    closest in angle to the ray). gap_tol: accepted off-ray miss at a jump, relative.
    """

    n_twists: int = DEFAULT_TWISTS_6D
    n_seeds: int = DEFAULT_SEEDS_6D
    rtol: float = 1e-12
    gap_tol: float = 2e-3
    problem: Problem6 | None = None
    fit_status: Status = Status.INVALID_INPUT
    fit_reason: str = 'not_fitted'
    fit_detail: str = 'call fit() first'
    diagnostics: dict = field(default_factory=dict)
    n_wrench_calls: int = 0

    def _eval(self, ts: np.ndarray) -> np.ndarray:
        assert self.problem is not None
        self.n_wrench_calls += 1
        sc = self.problem.scaling
        w = np.asarray(self.problem.wrench_fn(sc.twist_from_scaled(ts)), dtype=float)
        return sc.wrench_to_scaled(w)

    def fit(self, problem: Problem6) -> Surface6:
        self.problem = problem
        self.fit_status, self.fit_reason, self.fit_detail = Status.OK, '', ''
        if self.n_twists < 64:
            return self._fail(Status.DEGENERATE, 'too_few_twists',
                              f'{self.n_twists} twists: the 6D cloud needs at least 64')
        self._ts = sphere5(self.n_twists)
        ws = self._eval(self._ts)
        if not np.all(np.isfinite(ws)):
            return self._fail(Status.INVALID_INPUT, 'non_finite_wrench',
                              'wrench_fn returned non-finite values')
        self._ws = ws
        sv = np.linalg.svd(ws - ws.mean(axis=0), compute_uv=False)
        if not sv[-1] > 1e-9 * sv[0]:
            return self._fail(Status.DEGENERATE, 'flat_cloud',
                              f'the sampled 6D wrenches are flat (singular values {sv[0]:.3g} '
                              f'.. {sv[-1]:.3g}): no limit surface')
        g = problem.scaling.wrench_to_scaled(problem.gravity)
        gn = float(np.linalg.norm(g))
        if gn > 0.0:
            # W_0 = W_ext + W_g: the gravity-free surface; is W_g inside it?
            exit_g = self._first_exit(-g, g / gn, earlier_than=gn)
            self.diagnostics['support_exit_over_weight'] = (
                None if exit_g.s is None else exit_g.s / gn)
            if exit_g.s is None:
                return self._fail(Status.DEGENERATE, 'no_root',
                                  'support check: no twist balances the weight direction ('
                                  + exit_g.detail + ')')
            if exit_g.s <= gn:
                return self._fail(Status.UNSUPPORTED, 'origin_outside',
                                  f'the body cannot hold its weight in this pose: the '
                                  f'resistance along gravity ends at {exit_g.s / gn:.3g} x '
                                  'the weight')
        return self

    def _fail(self, status: Status, reason: str, detail: str) -> Surface6:
        self.fit_status, self.fit_reason, self.fit_detail = status, reason, detail
        return self

    @dataclass(frozen=True)
    class _Exit:
        s: float | None
        twist: np.ndarray | None
        residual: float
        n_roots: int
        detail: str

    def _first_exit(self, origin: np.ndarray, d: np.ndarray, earlier_than: float = math.inf,
                    extra_seeds: np.ndarray | None = None) -> _Exit:
        """First root of Ws(t) = origin + s d, s > 0 (scaled), from the cloud's best seeds.
        earlier_than: only crossings below this distance are worth an earlier-crossing search
        (the support check needs to know only whether one lies below the weight)."""
        y = self._ws - origin
        along = y @ d
        off = np.linalg.norm(y - along[:, None] * d, axis=1)
        angle = np.arctan2(off, along)
        order = np.argsort(angle)
        cand = order[along[order] > 0.0][: self.n_seeds]
        if len(cand) == 0:
            return self._Exit(None, None, math.inf, 0, 'no sampled wrench lies ahead on the ray')
        t, s, res, conv, iters = newton_on_sphere6(self._eval, origin, d, self._ts[cand],
                                                   self.rtol)
        for _round in range(EARLIER_ROUNDS):
            good = conv & (s > 0.0)
            if not np.any(good):
                break
            # An earlier crossing the closest-in-angle seeds missed (a fold): seed again from
            # cloud twists whose wrench lies ahead on the ray but short of the best root, within
            # EARLIER_ANGLE of it.
            s_best = min(float(s[good].min()), earlier_than)
            early = order[(along[order] > 0.0) & (along[order] < s_best * (1.0 - 1e-6))
                          & (angle[order] < EARLIER_ANGLE)]
            early = early[~np.isin(early, cand)][: self.n_seeds]
            if not len(early):
                break
            more = newton_on_sphere6(self._eval, origin, d, self._ts[early], self.rtol)
            t, s = np.vstack([t, more[0]]), np.r_[s, more[1]]
            res, conv = np.r_[res, more[2]], np.r_[conv, more[3]]
            cand = np.r_[cand, early]
        gap = ~conv & (res <= self.gap_tol * np.maximum(np.abs(s), 1e-3))
        ok = (conv | gap) & (s > 0.0)
        good = conv & (s > 0.0)
        s_conv = float(s[good].min()) if np.any(good) else math.inf
        # Seeds that stalled short of the first converged root (or all that stalled, when none
        # converged): the first crossing may sit on a switching set (a jump of the map, e.g.
        # the side faces of a symmetric body at a planar twist, or a plate sliding edge-on),
        # which free Newton cannot land on. Newton confined to that set, where RFT counts the
        # switching facets as leading, may still land on the ray exactly.
        earlier = ~conv & ((s < s_conv * (1.0 - 1e-6)) | (s_conv == math.inf))
        if np.any(earlier):
            stalled = np.argsort(np.where(earlier & (s > 0.0),
                                          res / np.maximum(np.abs(s), 1e-3), np.inf))
            stalled = stalled[earlier[stalled]]
            for kk in stalled[:STALLED_TRIES]:
                if s[kk] >= s_conv * (1.0 - 1e-6):
                    continue     # an exact root already lies before it
                hit = self._on_switching_set(t[kk], origin, d)
                if hit is not None:
                    exact = hit[2] <= self.rtol * max(hit[1], 1e-3)
                    t = np.vstack([t, hit[0]])
                    s, res = np.r_[s, hit[1]], np.r_[res, hit[2]]
                    conv, ok = np.r_[conv, exact], np.r_[ok, True]
                    if exact:
                        s_conv = min(s_conv, hit[1])
        # Extra seeds (the in-plane answers of a mirror plane off the pull plane, lifted): the
        # patch search from each finds the exit on the closure of the jump across the plane
        # (a pull yawed off a plate's slide exits there), or a root when the patch shrinks
        # onto a smooth crossing. Only an exit earlier than all others is kept.
        bridged = False
        is_bridge = np.zeros(len(s), dtype=bool)
        s_now = min(s_conv, earlier_than)
        for seed in (() if extra_seeds is None else unit_rows(np.asarray(extra_seeds, float))):
            hit = self._closure_patch(seed, origin, d)
            exact = hit is not None and hit[2] <= self.rtol * max(hit[1], 1e-3)
            if hit is None or not hit[1] < s_now * (1.0 - 1e-6):
                continue
            t, s, res = np.vstack([t, hit[0]]), np.r_[s, hit[1]], np.r_[res, hit[2]]
            conv, ok = np.r_[conv, exact], np.r_[ok, True]
            is_bridge = np.r_[is_bridge, not exact]
            if not exact:
                ok &= conv | is_bridge   # a bridged exit: preferred to gap-accepted twists
                bridged = True
            s_now = hit[1]
        if not np.any(conv & (s > 0.0)):
            # Still nothing exact: the ray passes a jump. Its exit on the closure (the jump
            # bridged linearly, docs/design/closure.md) from a shrinking patch around the best
            # stalled seed; preferred to a gap-accepted twist, whose distance is off by the gap.
            stalled = np.argsort(np.where(s > 0.0, res / np.maximum(np.abs(s), 1e-3), np.inf))
            patch = self._closure_patch(t[stalled[0]], origin, d)
            if patch is not None:
                t, s = np.vstack([t, patch[0]]), np.r_[s, patch[1]]
                res = np.r_[res, patch[2]]
                conv, ok = np.r_[conv, False], np.r_[ok & is_bridge, True]
                bridged = True
        roots = np.unique(np.round(s[ok] / (1e-7 * max(float(np.max(np.abs(s))), 1e-300))))
        if not np.any(ok):
            return self._Exit(None, None, float(res.min()), 0,
                              f'{len(cand)} seeds, none converged (best residual '
                              f'{float(res.min()):.2g}, {iters} iterations)')
        k = int(np.flatnonzero(ok)[np.argmin(s[ok])])
        return self._Exit(float(s[k]), t[k], float(res[k]), len(roots),
                          f'{len(cand)} seeds, {int(conv[:len(cand)].sum())} converged, '
                          f'{len(roots)} distinct roots, {iters} iterations'
                          + ('; exit on the closure of a jump (patch search)' if bridged
                             else '; landed on a switching set' if len(conv) > len(cand)
                             else ''))

    def _closure_patch(self, t_b: np.ndarray, origin: np.ndarray, d: np.ndarray,
                       radius: float = 0.05, angle_tol: float = 1e-8, max_iter: int = 120
                       ) -> tuple[np.ndarray, float, float] | None:
        """Exit of the ray through the closure of the map near t_b: the 6D analogue of
        surfaces/closure.py. Around t, 11 twists (t and t +- radius along the 5 tangent
        directions) give a least-squares affine model of the wrench over the patch; a patch
        that straddles a switching set bridges the jump linearly, as the closure does. The
        model's ray crossing moves t (at most one radius); when it falls inside the patch the
        radius halves. Returns (twist, s, miss) once the radius is below angle_tol (miss: the
        off-ray residual of the twist itself, the jump size), else None."""
        proj = complement_basis(d)
        t = unit_rows(t_b[None])[0]
        rho = radius
        s_model = math.nan
        history: list[float] = []
        for _ in range(max_iter):
            basis = _householder_bases(t[None])[0]                  # (5, 6)
            pts = unit_rows(np.vstack([t, t + rho * basis, t - rho * basis]))
            w = self._eval(pts) - origin
            coords = np.column_stack([np.ones(len(pts)), (pts - t) @ basis.T])
            coef = np.linalg.lstsq(coords, w, rcond=None)[0]         # (6 params, 6 outputs)
            a0, g = coef[0], coef[1:].T                                # (6,), (6, 5)
            c = np.linalg.lstsq(proj @ g, -(proj @ a0), rcond=None)[0]
            s_model = float(d @ (a0 + g @ c))
            step = float(np.linalg.norm(c))
            if step > rho:
                c *= rho / step
            else:
                rho *= 0.5
            t = unit_rows((t + c @ basis)[None])[0]
            history.append(s_model)
            if rho < angle_tol:
                break
        # Where several switching sets meet, the crossing may not stay inside a smaller patch
        # (as in closure.py): accept when the last model distances agree to SETTLED_RTOL.
        settled = (len(history) >= 4 and max(history[-4:]) - min(history[-4:])
                   <= SETTLED_RTOL * abs(history[-1]))
        if not ((rho < angle_tol or settled) and s_model > 0.0 and math.isfinite(s_model)):
            return None
        w_t = self._eval(t[None])[0] - origin
        return t, s_model, float(np.linalg.norm(proj @ w_t))

    def _on_switching_set(self, t_b: np.ndarray, origin: np.ndarray, d: np.ndarray,
                          max_iter: int = 30) -> tuple[np.ndarray, float, float] | None:
        """Gauss-Newton on the switching set of the facets nearly switching at t_b.

        For tolerances delta = 1e-6 .. 1e-2: J = facets with |b_j . t_b| < delta (b_j the
        scaled, normalised switch forms); their switching set is the null space N of b_J, a
        linear subspace of twists. Starting from t_b projected onto it, Gauss-Newton in that
        subspace (least squares on the 5 residuals). Returns (twist, s, residual) when the
        residual vanishes (rtol); else the set's closest approach to the ray when it misses by
        at most gap_tol of the distance (a gap candidate: a set of dimension 1 or 2, e.g. a box
        pulled straight up, may not contain the root); else None."""
        assert self.problem is not None
        a = self.problem.switch_forms
        if a is None or len(a) == 0:
            return None
        b = unit_rows(a / self.problem.scaling.diag)     # a . t = (a / S) . (S t)
        proj = complement_basis(d)
        h = 1e-7
        lead = np.abs(b @ t_b)
        line: tuple[np.ndarray, float, float] | None = None
        for delta in (1e-6, 1e-4, 1e-3, 1e-2):
            rows = b[lead < delta]
            if len(rows) == 0:
                continue
            _, sv, vt = np.linalg.svd(rows, full_matrices=True)
            rank = int(np.sum(sv > 1e-9 * sv[0]))
            null = vt[rank:]                               # (k, 6) orthonormal rows
            if len(null) == 1:
                # The switching set is one line (e.g. a box pulled straight up: every side
                # facet switches only on the pure translation): no Newton, the twist is fixed.
                # Its miss is the jump the ray passes; kept as a gap candidate (gap_tol).
                t = null[0] * (1.0 if null[0] @ t_b >= 0.0 else -1.0)
                w = self._eval(t[None])[0] - origin
                s_line, miss = float(w @ d), float(np.linalg.norm(proj @ w))
                if s_line > 0.0 and miss <= self.gap_tol * s_line and (
                        line is None or miss < line[2]):
                    line = (t, s_line, miss)
                continue
            if len(null) < 2:
                continue
            t = null.T @ (null @ t_b)
            if np.linalg.norm(t) < 1e-6:
                continue
            t /= np.linalg.norm(t)
            best = None
            lam, step, basis = 1.0, np.zeros(len(null) - 1), np.zeros((len(null) - 1, 6))
            cur_t = t
            for _ in range(max_iter):
                c = null @ cur_t
                tb = _householder_bases(c[None])[0] @ null      # (k-1, 6) tangent, in N
                batch = np.vstack([cur_t, unit_rows(cur_t + h * tb)])
                w = self._eval(batch) - origin
                r = proj @ w[0]
                rn, s_now = float(np.linalg.norm(r)), float(w[0] @ d)
                if best is None or rn < best[2]:
                    best = (cur_t, s_now, rn)
                    jac = (proj @ (w[1:] - w[0]).T) / h         # (5, k-1)
                    step = -np.linalg.lstsq(jac, r, rcond=None)[0]
                    nrm = float(np.linalg.norm(step))
                    step *= min(1.0, 0.3 / max(nrm, 1e-300))
                    basis, lam = tb, 1.0
                    if rn <= self.rtol * max(abs(s_now), 1e-3):
                        break
                else:
                    lam *= 0.5
                    if lam < 1e-6:
                        break
                cur_t = unit_rows(best[0] + lam * step @ basis)
            if best is not None and best[1] > 0.0 and best[2] <= self.rtol * max(best[1], 1e-3):
                return best
            if best is not None and 0.0 < best[1] and best[2] <= self.gap_tol * best[1] and (
                    line is None or best[2] < line[2]):
                line = best     # the set's closest approach to the ray: a gap candidate
        return line

    def capacity(self, direction: np.ndarray, in_plane: InPlane6 | None = None,
                 seeds: np.ndarray | None = None) -> Result6:
        """Capacity along the unit force direction (3,) (the tether's pull, world), no moment
        about p.

        in_plane: the sagittal answer lifted into 6D, when the posed anchor is mirror-symmetric
        about the pull plane (posed.py checks it). Its twist maps onto the ray in 6D too (planar
        twists give planar wrenches there), so it is a crossing of the 6D ray; it is checked on
        the 6D map and kept as a candidate. The sagittal root often lies on the switching set
        of the edge-on facets, where free Newton from the cloud cannot land, and on folded
        surfaces (a plate pulled up) it is the first exit the cloud's seeds miss. The answer
        is the smaller of it and the 6D search's first exit (which may lie out of the plane:
        then the sagittal reduction alone would have missed it).

        seeds: extra scaled twists (K, 6) to start from (`_first_exit`), e.g. the in-plane
        answers of a mirror plane near the pull plane."""
        if self.fit_status is not Status.OK:
            return Result6(self.fit_status, reason=self.fit_reason, detail=self.fit_detail)
        assert self.problem is not None
        u = np.asarray(direction, dtype=float).reshape(3)
        if not (np.all(np.isfinite(u)) and abs(np.linalg.norm(u) - 1.0) < 1e-9):
            return Result6(Status.INVALID_INPUT, reason='invalid_phi',
                           detail=f'pull direction {u.tolist()} is not a unit vector')
        d = np.r_[u, 0.0, 0.0, 0.0]
        ex = self._first_exit(np.zeros(6), d, extra_seeds=seeds)
        sf = self.problem.scaling.force_N
        plane = self._check_in_plane(in_plane, d) if in_plane is not None else None
        # The 6D search's exit replaces the in-plane answer only when it is an exact root
        # before it (an out-of-plane crossing). A bridged or gap-accepted exit before it
        # straddles the jump across the edge-on facets' switching set, where the in-plane
        # answer keeps RFT's value at n . v = 0 (the convention both paths use, see
        # docs/design/six-d.md); it is reported in the detail.
        ex_exact = ex.s is not None and ex.residual <= self.rtol * max(ex.s, 1e-3)
        if plane is not None and (ex.s is None or not ex_exact
                                  or plane[0] <= ex.s * (1.0 + IN_PLANE_RTOL)):
            s_p, ts_p, note, _ = plane
            assert in_plane is not None
            flags = tuple(f for f in in_plane.flags if f == 'on_jump')
            more = ex.s is not None and abs(ex.s - s_p) > IN_PLANE_RTOL * s_p
            if more or 'multiple_crossings' in in_plane.flags:
                flags += ('multiple_crossings',)
            detail = (note + '; 6D search: ' + ex.detail
                      + ('' if ex.s is None else f' (first exit {ex.s * sf:.6g} N'
                         + ('' if ex_exact else ', on a jump') + ')'))
            raw = self.problem.scaling.twist_from_scaled(ts_p)
            return Result6(Status.OK, capacity_N=s_p * sf,
                           slip_twist=tuple(float(v) for v in raw),
                           slip_twist_scaled=tuple(float(v) for v in ts_p),
                           n_hits=max(ex.n_roots, 1), detail=detail, flags=flags,
                           unchecked_capacity_N=s_p * sf)
        if ex.s is None or ex.twist is None:
            return Result6(Status.DEGENERATE, reason='no_root', detail=ex.detail)
        flags = ()
        detail = ex.detail
        if in_plane is not None:
            detail += ('; in-plane answer not confirmed on the 6D map' if plane is None else
                       f'; an out-of-plane crossing lies before the in-plane one '
                       f'({plane[0] * sf:.6g} N)')
        if ex.residual > self.rtol * max(ex.s, 1e-3):
            flags = ('on_jump',)
            detail += (f'; the ray passes a jump of the RFT map: nearest twist misses it by '
                       f'{ex.residual / ex.s:.2g} of the distance')
        if ex.n_roots > 1 or plane is not None:
            flags += ('multiple_crossings',)
        ts = unit_rows(ex.twist)
        raw = self.problem.scaling.twist_from_scaled(ts)
        return Result6(Status.OK, capacity_N=ex.s * sf,
                       slip_twist=tuple(float(v) for v in raw),
                       slip_twist_scaled=tuple(float(v) for v in ts), n_hits=ex.n_roots,
                       detail=detail, flags=flags, unchecked_capacity_N=ex.s * sf)

    def _check_in_plane(self, cand: InPlane6, d: np.ndarray
                        ) -> tuple[float, np.ndarray, str, bool] | None:
        """(s, scaled twist, note, exact) when the lifted in-plane answer is a crossing of the
        6D ray. Its twist must carry no out-of-plane wrench on the 6D map (to IN_PLANE_RTOL:
        the 6D map there is the in-plane one). Then: an exact root when its wrench lies on the
        ray at the in-plane distance to IN_PLANE_RTOL; an exit on the closure of an in-plane
        jump (flag on_jump: the jump is bridged between one-sided limits of planar twists,
        which are limits of the 6D map too); or an answer the sagittal path accepted off the
        ray by at most gap_tol of the distance (as the 6D search accepts one). Else None."""
        assert self.problem is not None
        ts = np.asarray(cand.twist_scaled, dtype=float).reshape(6)
        if not (cand.capacity_N > 0.0 and np.all(np.isfinite(ts))
                and np.linalg.norm(ts) > 0.0):
            return None
        ts = ts / np.linalg.norm(ts)
        s_p = cand.capacity_N / self.problem.scaling.force_N
        w = self._eval(ts[None])[0]
        miss = float(np.linalg.norm(complement_basis(d) @ w)) / s_p
        along = abs(float(w @ d) - s_p) / s_p
        n = np.asarray(cand.plane_normal, dtype=float)
        wn = max(float(np.linalg.norm(w)), 1e-300)
        out = math.hypot(float(w[:3] @ n), float(np.linalg.norm(np.cross(w[3:], n)))) / wn
        if out > IN_PLANE_RTOL:
            return None
        if miss <= IN_PLANE_RTOL and along <= IN_PLANE_RTOL:
            return s_p, ts, f'in-plane root, on the 6D ray to {max(miss, along):.2g}', True
        if 'on_jump' in cand.flags:
            return s_p, ts, (f'in-plane exit on the closure of a jump (the twist itself '
                             f'{miss:.2g} of the distance off the ray, no out-of-plane '
                             f'wrench to {out:.2g})'), False
        if miss <= self.gap_tol:
            return s_p, ts, (f'in-plane answer {miss:.2g} of the distance off the 6D ray (as '
                             'on the sagittal path)'), False
        return None
