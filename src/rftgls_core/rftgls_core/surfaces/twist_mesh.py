"""Twist-sphere mesh: triangulate the twists once on the sphere, reuse it for every pose.

t -> W_ext(t) maps the unit sphere of scaled twists onto the limit surface, so a triangulation
of the sphere (the convex hull of the unit twists = their spherical Delaunay triangulation) is a
closed genus-0 mesh of the surface once its vertices are moved to the wrenches. Each vertex
carries its twist, so the slip twist at a hit is the barycentric blend of the three vertex
twists (renormalised). Only the wrenches change from pose to pose: fitting a pose is one
wrench_fn call plus the ray precompute (docs/design/limit-surfaces.md).

Per-pose checks, in the scaled wrench space:
- folds: faces whose outward normal points toward the origin (n . centroid <= 0). They mean the
  map folds over or the surface is not star-shaped about the origin.
- winding number of the mesh about the origin: 1 inside, 0 outside (-> UNSUPPORTED).
- per ray: exactly one crossing; the hit face is not folded; the twist at the hit is unique
  (no vertex of the hit face sits on a collapsed edge, i.e. many twists -> one wrench).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy.spatial import ConvexHull

from ..types import Status
from .base import CapacityResult, FitInfo, GLSProblem, LimitSurface, evaluate_wrenches
from .diagnostics import collapsed_vertices, face_normals, fold_mask, unique_edges
from .newton import newton_on_sphere
from .raycast import PreparedMesh, cast_rays, prepare_mesh, winding_number
from .sampling import fibonacci_sphere


def orient_outward(points: np.ndarray, faces: np.ndarray,
                   centre: np.ndarray | None = None) -> np.ndarray:
    """Reorder each face (F, 3) so its right-hand normal points away from `centre` (default 0)."""
    c = np.zeros(3) if centre is None else np.asarray(centre, dtype=float)
    f = np.array(faces, dtype=np.intp, copy=True)
    n = face_normals(points, f)
    centroid = points[f].mean(axis=1) - c
    flip = np.einsum('ij,ij->i', n, centroid) < 0.0
    f[flip, 1], f[flip, 2] = f[flip, 2].copy(), f[flip, 1].copy()
    return f


@dataclass(frozen=True)
class TwistSphere:
    """n unit scaled twists (Fibonacci) and their outward sphere triangulation (2n - 4 faces).

    Independent of the pose and of the scaling (the scaling only changes the raw twists), so
    one instance serves a whole state-space map.
    """

    twists_scaled: np.ndarray   # (n, 3) unit vectors
    faces: np.ndarray           # (2n-4, 3) vertex indices, outward

    @property
    def n(self) -> int:
        return len(self.twists_scaled)

    @classmethod
    def build(cls, n: int) -> 'TwistSphere':
        return _sphere(int(n))

    def twists_raw(self, problem: GLSProblem) -> np.ndarray:
        return problem.scaling.twist_from_scaled(self.twists_scaled)

    def wrenches(self, problem: GLSProblem) -> tuple[np.ndarray | None, str]:
        """Raw W_ext at every sphere twist (one batched call), or (None, why) if not finite."""
        return evaluate_wrenches(problem, self.twists_raw(problem))

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2): the same for every pose, so computed once."""
        return unique_edges(self.faces)[0]


@lru_cache(maxsize=8)
def _sphere(n: int) -> TwistSphere:
    ts = fibonacci_sphere(n)
    hull = ConvexHull(ts)
    if len(hull.vertices) != n:
        raise RuntimeError(f'sphere hull dropped {n - len(hull.vertices)} of {n} twists')
    faces = orient_outward(ts, hull.simplices)
    faces.setflags(write=False)
    ts.setflags(write=False)
    return TwistSphere(twists_scaled=ts, faces=faces)


class TwistMeshSurface(LimitSurface):
    """The twist-sphere mesh representation (primary engine).

    n_twists: sphere resolution (ignored when `sphere` is given).
    sphere: a shared TwistSphere, to reuse one connectivity across many poses.
    pinch_ratio: a mesh edge is 'collapsed' (many twists -> one wrench) when its wrench-space
        length per radian of twist is below pinch_ratio times the median over all edges.
    """

    method = 'twist-mesh'

    def __init__(self, n_twists: int = 2000, sphere: TwistSphere | None = None,
                 pinch_ratio: float = 1e-3, polish: bool = True, gap_tol: float = 2e-3) -> None:
        super().__init__(n_twists if sphere is None else sphere.n)
        self.sphere = sphere
        self.pinch_ratio = float(pinch_ratio)
        self.polish = bool(polish)
        self.gap_tol = float(gap_tol)
        self.wrenches_scaled: np.ndarray | None = None
        self._mesh: PreparedMesh | None = None

    # -- fitting ---------------------------------------------------------------------------
    def fit(self, problem: GLSProblem, n_twists: int | None = None) -> 'TwistMeshSurface':
        if n_twists is not None and (self.sphere is None or self.sphere.n != int(n_twists)):
            self.sphere, self.n_twists = None, int(n_twists)
        if self.sphere is None:
            if self.n_twists < 8:
                self.problem = problem
                return self._fail_fit(Status.DEGENERATE, 'too_few_twists',
                                      f'{self.n_twists} twists cannot triangulate a sphere '
                                      '(need >= 8, about 2000 recommended)')
            self.sphere = TwistSphere.build(self.n_twists)
        w, why = self.sphere.wrenches(problem)
        if w is None:
            self.problem = problem
            return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench', why)
        return self.fit_wrenches(problem, w)

    def fit_wrenches(self, problem: GLSProblem, wrenches: np.ndarray) -> 'TwistMeshSurface':
        """Fit from precomputed raw W_ext (n, 3), ordered like sphere.twists_raw(problem)."""
        self.problem = problem
        w = np.asarray(wrenches, dtype=float)
        if self.sphere is None or w.shape != (self.sphere.n, 3):
            raise ValueError('wrenches must be (n, 3) and ordered like the sphere twists')
        if not np.all(np.isfinite(w)):
            return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench',
                                  'wrenches contain NaN or inf')
        ws = problem.scaling.wrench_to_scaled(w)
        faces = self.sphere.faces
        self.wrenches_scaled = ws
        self._mesh = prepare_mesh(ws, faces)
        folds = fold_mask(ws, faces)
        self._folded = folds
        self._pinched = collapsed_vertices(ws, self.sphere.twists_scaled, faces,
                                           self.pinch_ratio, edges=self.sphere.edges)
        wind = winding_number(ws, faces)
        diag = {'n_twists': self.sphere.n, 'n_faces': len(faces), 'folds': int(folds.sum()),
                'winding_number': wind, 'pinched_vertices': int(self._pinched.sum())}
        self.fit_info = FitInfo(diagnostics=diag)
        if abs(wind) < 0.5:
            return self._fail_fit(Status.UNSUPPORTED, 'origin_outside',
                                  f'origin outside the limit surface (winding {wind:.3f}): the '
                                  'legs cannot hold the robot in this pose')
        if abs(wind - 1.0) > 0.1:
            return self._fail_fit(Status.DEGENERATE, 'bad_winding',
                                  f'winding number {wind:.3f} about the origin (expected 1): '
                                  f'the mesh folds ({int(folds.sum())} folded faces)')
        self.fit_info.detail = (f'{len(faces)} faces, {int(folds.sum())} folded, '
                                f'{int(self._pinched.sum())} pinched vertices')
        return self

    # -- queries ---------------------------------------------------------------------------
    def _capacity_many(self, phis: np.ndarray) -> list[CapacityResult]:
        problem = self.problem
        dirs = np.stack([problem.load_direction_scaled(p) for p in phis])
        hits = cast_rays(self._mesh, dirs)
        faces = self.sphere.faces
        ts_all = self.sphere.twists_scaled
        s_f = problem.scaling.force_N
        out = []
        for k, phi in enumerate(phis):
            nh, f = int(hits.n_hits[k]), int(hits.face[k])
            if f < 0:
                out.append(CapacityResult.make(
                    phi, Status.DEGENERATE, self.method, None, n_hits=0, reason='no_hit',
                    detail='ray from the origin never leaves the mesh although the winding '
                           'number says the origin is inside'))
                continue
            cap = float(hits.s[k]) * s_f
            tw = hits.bary[k] @ ts_all[faces[f]]
            tw = tw / np.linalg.norm(tw) if np.linalg.norm(tw) > 0 else tw
            edge = ' (through an edge/vertex, counted once)' if hits.on_edge[k] else ''
            detail = f'hits {nh}{edge}; folds {int(self._folded.sum())}'
            status, reason = Status.OK, ''
            if nh > 1:
                status, reason = Status.DEGENERATE, 'multiple_hits'
                detail += '; ray crosses the surface more than once (first exit used)'
            elif self._folded[f]:
                status, reason = Status.DEGENERATE, 'folded_face'
                detail += '; the hit face is folded toward the origin'
            elif np.any(self._pinched[faces[f]] & (hits.bary[k] > 1e-3)):
                status, reason = Status.DEGENERATE, 'non_unique_twist'
                detail += ('; the hit face touches a pinch where many twists give one wrench: '
                           'the slip twist is not determined')
            if status is Status.OK and self.polish:
                cap, tw, detail = self._polish(phi, f, tw, cap, detail)
            out.append(CapacityResult.make(phi, status, self.method, cap, tw, problem.scaling,
                                           n_hits=nh, reason=reason, detail=detail))
        return out

    def _polish(self, phi: float, face: int, seed: np.ndarray, cap: float, detail: str):
        """Move the hit from the flat facet onto the true surface (Newton from its twist).

        Facets are chords: on real RFT surfaces, whose wrench density varies strongly over the
        twist sphere, the chord sits up to ~20 % inside the surface at 1,000 twists. A few
        Newton steps from the barycentric twist remove that error; a root is accepted only
        near the hit face (the mesh keeps the topology decisions: first exit, folds).
        """
        problem = self.problem
        sc = problem.scaling
        d = problem.load_direction_scaled(phi)
        eval_scaled = lambda ts: sc.wrench_to_scaled(problem.wrenches(sc.twist_from_scaled(ts)))
        corners = self.sphere.twists_scaled[self.sphere.faces[face]]
        reach = 3.0 * float(np.arccos(np.clip(corners @ seed, -1.0, 1.0)).max()) + 1e-3

        def solve(seeds, max_iter):
            t, s, res, _, conv, iters = newton_on_sphere(eval_scaled, d, seeds, rtol=1e-10,
                                                         max_iter=max_iter)
            near = np.arccos(np.clip(t @ seed, -1.0, 1.0)) <= reach
            ok = (conv | (res <= self.gap_tol * np.abs(s))) & (s > 0.0) & near
            return t, s, res, ok, iters

        # The hit's own twist usually converges in a few steps; only when it does not, the
        # face corners are tried too (steep maps defeat a single seed).
        t, s, res, ok, iters = solve(seed[None, :], 25)
        if not np.any(ok):
            t, s, res, ok, iters = solve(np.vstack([seed, corners]), 40)
        if not np.any(ok):
            return cap, seed, detail + '; not polished (no root near the hit face: mesh value)'
        k = int(np.flatnonzero(ok)[np.argmin(s[ok])])  # first exit among the local roots
        cap_polished = float(s[k]) * sc.force_N
        return cap_polished, t[k], detail + (f'; polished in {iters} steps (mesh chord '
                                             f'{cap:.4g} N, residual {res[k]:.1e})')
