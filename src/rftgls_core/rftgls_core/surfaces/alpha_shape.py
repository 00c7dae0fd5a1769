"""Alpha shapes with MATLAB `alphaShape` semantics, on scipy.spatial.Delaunay.

Semantics (docs/design/limit-surfaces.md; inferred from MATLAB's documented behaviour):
- regularised: the solid is exactly the union of Delaunay tetrahedra with circumradius
  R <= alpha (alpha is a RADIUS; alpha = inf gives the convex hull, 0 an empty shape);
- spectrum: the distinct finite circumradii, descending;
- criticalAlpha('all-points'): smallest alpha whose solid touches every point;
  criticalAlpha('one-region'): smallest alpha covering all points in exactly one region;
- regions are face-connected components of kept tetrahedra; voids are components of the
  complement (R > alpha) not connected to the outside;
- the paper's rule: the median of the spectrum values that cover all points with one region
  and no voids (numpy median);
- for a GLS, voids are filled (HoleThreshold = inf) so a ray from the origin cannot stop on an
  inner void wall; boundary faces are oriented outward.

All criteria for every spectrum value in O(T log T): regions from a minimum spanning forest of
the tetrahedron adjacency graph with edge weight max(R_i, R_j); voids from a maximum spanning
forest of the complement graph (weights min(R_i, R_j), plus an outside node).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, minimum_spanning_tree
from scipy.spatial import Delaunay, QhullError

from ..types import Status
from .base import CapacityResult, FitInfo, GLSProblem, LimitSurface, evaluate_wrenches
from .diagnostics import MeshTopology, mesh_topology
from .raycast import cast_rays, prepare_mesh, winding_number
from .sampling import sample_twists

# Local faces of a tetrahedron: face j is opposite vertex j.
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def circumradii(points: np.ndarray, simplices: np.ndarray, rel_vol_tol: float = 1e-12
                ) -> np.ndarray:
    """Circumradius (T,) of each tetrahedron; inf for slivers (|a.(b x c)| tiny) or non-finite."""
    p = np.asarray(points, dtype=float)
    s = np.asarray(simplices, dtype=np.intp)
    p0 = p[s[:, 0]]
    a, b, c = p[s[:, 1]] - p0, p[s[:, 2]] - p0, p[s[:, 3]] - p0
    bxc, cxa, axb = np.cross(b, c), np.cross(c, a), np.cross(a, b)
    vol6 = np.einsum('ij,ij->i', a, bxc)
    extent = float(np.ptp(p, axis=0).max()) if len(p) else 1.0
    ok = np.abs(vol6) > rel_vol_tol * extent ** 3
    num = (np.sum(a * a, axis=1)[:, None] * bxc + np.sum(b * b, axis=1)[:, None] * cxa
           + np.sum(c * c, axis=1)[:, None] * axb)
    with np.errstate(divide='ignore', invalid='ignore'):
        r = np.linalg.norm(num / (2.0 * vol6[:, None]), axis=1)
    return np.where(ok & np.isfinite(r), r, np.inf)


def _rank_weights(values: np.ndarray) -> np.ndarray:
    """1-based ranks (ties share nothing; order is all that spanning forests need).

    minimum_spanning_tree treats 0 as 'no edge', hence 1-based.
    """
    order = np.argsort(values, kind='stable')
    ranks = np.empty(len(values), dtype=float)
    ranks[order] = np.arange(1, len(values) + 1)
    return ranks


def _forest_edge_weights(n_nodes: int, i: np.ndarray, j: np.ndarray, w: np.ndarray,
                         maximum: bool = False) -> np.ndarray:
    """Weights (original values) of the edges of a min (or max) spanning forest."""
    if len(i) == 0:
        return np.zeros(0)
    key = -w if maximum else w
    ranks = _rank_weights(key)
    g = coo_matrix((ranks, (i, j)), shape=(n_nodes, n_nodes)).tocsr()
    mst = minimum_spanning_tree(g).tocoo()
    # Map ranks back to the original weights.
    by_rank = np.empty(len(w))
    by_rank[(ranks - 1).astype(np.intp)] = w
    return by_rank[(mst.data - 1).astype(np.intp)]


@dataclass(frozen=True)
class AlphaCriteria:
    """Per spectrum value (descending): covers all points, number of regions, number of voids."""

    spectrum: np.ndarray
    all_points: np.ndarray
    regions: np.ndarray
    voids: np.ndarray
    alpha_all_points: float
    alpha_one_region: float

    @property
    def passing(self) -> np.ndarray:
        return self.spectrum[self.all_points & (self.regions == 1) & (self.voids == 0)]

    @property
    def alpha_paper(self) -> float:
        """Median of the alphas giving one closed region (the paper's rule); nan if none."""
        p = self.passing
        return float(np.median(p)) if len(p) else float('nan')


def _absorb_slivers(radii: np.ndarray, neighbors: np.ndarray) -> np.ndarray:
    """Give each flat tetrahedron (R = inf) the smallest radius of its neighbours.

    A sliver has no volume, so it joins the solid together with a neighbour; left at
    R = inf it would stay outside at every alpha and count as an enclosed void forever (seen
    on real RFT clouds: one sliver made the paper's rule find no passing alpha at all).
    """
    r = radii.copy()
    bad = np.flatnonzero(~np.isfinite(r))
    if len(bad) == 0:
        return r
    finite_max = float(np.max(r[np.isfinite(r)], initial=1.0))
    for _ in range(4):  # slivers next to slivers: propagate a few times
        nb = neighbors[bad]
        nb_r = np.where(nb >= 0, r[np.maximum(nb, 0)], np.inf)
        r[bad] = nb_r.min(axis=1)
        bad = np.flatnonzero(~np.isfinite(r))
        if len(bad) == 0:
            break
    r[bad] = finite_max
    return r


class AlphaComplex:
    """Delaunay tetrahedra of a (scaled, de-duplicated) point cloud and their circumradii."""

    def __init__(self, points: np.ndarray) -> None:
        pts = np.asarray(points, dtype=float)
        extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
        key = np.round(pts / max(extent, 1e-300) * 1e12)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        self.points = pts[first]           # unique points
        self.source_index = first          # unique point -> first input index
        self.inverse = inverse.ravel()     # input index -> unique point
        try:
            self.tri = Delaunay(self.points)
        except QhullError:
            # Degenerate input (e.g. cospherical or flat): joggle, documented Qhull fallback.
            self.tri = Delaunay(self.points, qhull_options='QJ')
        self.simplices = self.tri.simplices
        self.neighbors = self.tri.neighbors
        self.radii = _absorb_slivers(circumradii(self.points, self.simplices), self.tri.neighbors)
        t = len(self.simplices)
        i = np.repeat(np.arange(t), 4)
        j = self.neighbors.ravel()
        m = (j > i)
        self._adj = (i[m], j[m])
        self._hull_tets = np.unique(np.flatnonzero((self.neighbors < 0).any(axis=1)))

    @property
    def n_tets(self) -> int:
        return len(self.simplices)

    def spectrum(self) -> np.ndarray:
        """Distinct finite circumradii, descending (MATLAB alphaSpectrum)."""
        r = self.radii[np.isfinite(self.radii)]
        return np.unique(r)[::-1]

    def criteria(self) -> AlphaCriteria:
        """All three criteria for every spectrum value (see module docstring)."""
        spec = self.spectrum()
        asc = spec[::-1]
        r = self.radii
        t = self.n_tets
        # all points: smallest incident radius per point, then the max over points.
        rmin = np.full(len(self.points), np.inf)
        np.minimum.at(rmin, self.simplices.ravel(), np.repeat(r, 4))
        a_all = float(rmin.max())
        # regions = #kept tets - #MSF edges with weight <= a.
        i, j = self._adj
        keep_edge = np.isfinite(r[i]) & np.isfinite(r[j])
        w_max = np.maximum(r[i], r[j])[keep_edge]
        msf = np.sort(_forest_edge_weights(t, i[keep_edge], j[keep_edge], w_max))
        r_sorted = np.sort(r[np.isfinite(r)])
        n_kept = np.searchsorted(r_sorted, asc, side='right')
        regions = n_kept - np.searchsorted(msf, asc, side='right')
        # voids: complement graph (R > a) plus an outside node joined to the hull tets.
        out = t
        ci = np.concatenate([i, self._hull_tets])
        cj = np.concatenate([j, np.full(len(self._hull_tets), out)])
        cw = np.concatenate([np.minimum(r[i], r[j]), r[self._hull_tets]])
        finite_w = np.where(np.isfinite(cw), cw, np.finfo(float).max)
        maxsf = np.sort(_forest_edge_weights(t + 1, ci, cj, finite_w, maximum=True))
        all_r = np.sort(np.where(np.isfinite(r), r, np.finfo(float).max))
        n_comp_nodes = (t - np.searchsorted(all_r, asc, side='right')) + 1
        n_edges_above = len(maxsf) - np.searchsorted(maxsf, asc, side='right')
        voids = n_comp_nodes - n_edges_above - 1
        all_pts = asc >= a_all
        one = all_pts & (regions == 1)
        a_one = float(asc[one][0]) if np.any(one) else float('inf')
        rev = slice(None, None, -1)
        return AlphaCriteria(spectrum=spec, all_points=all_pts[rev], regions=regions[rev],
                             voids=voids[rev], alpha_all_points=a_all, alpha_one_region=a_one)

    def critical_alpha(self, kind: str = 'all-points') -> float:
        c = self.criteria()
        if kind == 'all-points':
            return c.alpha_all_points
        if kind == 'one-region':
            return c.alpha_one_region
        raise ValueError(f"kind must be 'all-points' or 'one-region', got {kind!r}")

    # -- the solid for one alpha ----------------------------------------------------------
    def solid(self, alpha: float, fill_voids: bool = True) -> np.ndarray:
        """(T,) bool mask of kept tetrahedra: R <= alpha, plus enclosed voids if asked."""
        keep = self.radii <= alpha
        if fill_voids:
            keep = keep | self.void_mask(keep)
        return keep

    def void_mask(self, keep: np.ndarray) -> np.ndarray:
        """Tetrahedra of complement components that do not reach the outside."""
        t = self.n_tets
        i, j = self._adj
        m = ~keep[i] & ~keep[j]
        hull = self._hull_tets[~keep[self._hull_tets]]
        ii = np.concatenate([i[m], hull])
        jj = np.concatenate([j[m], np.full(len(hull), t)])
        g = coo_matrix((np.ones(len(ii)), (ii, jj)), shape=(t + 1, t + 1))
        _, lab = connected_components(g, directed=False)
        return ~keep & (lab[:t] != lab[t])

    def count_regions(self, keep: np.ndarray) -> int:
        i, j = self._adj
        m = keep[i] & keep[j]
        idx = np.flatnonzero(keep)
        if len(idx) == 0:
            return 0
        g = coo_matrix((np.ones(int(m.sum())), (i[m], j[m])), shape=(self.n_tets, self.n_tets))
        _, lab = connected_components(g, directed=False)
        return len(np.unique(lab[idx]))

    def boundary_faces(self, keep: np.ndarray) -> np.ndarray:
        """Outward-oriented boundary triangles (F, 3) of the kept solid (unique-point indices)."""
        nb = self.neighbors
        other_kept = np.where(nb >= 0, keep[np.maximum(nb, 0)], False)
        bnd = keep[:, None] & ~other_kept                     # (T, 4): face j is boundary
        ti, fj = np.nonzero(bnd)
        simp = self.simplices[ti]
        faces = np.take_along_axis(simp, _TET_FACES[fj], axis=1)
        opposite = self.points[simp[np.arange(len(ti)), fj]]
        p = self.points
        n = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
        inward = np.einsum('ij,ij->i', n, opposite - p[faces[:, 0]]) > 0.0
        faces[inward, 1], faces[inward, 2] = faces[inward, 2].copy(), faces[inward, 1].copy()
        return faces


@dataclass(frozen=True)
class AlphaShape:
    """A regularised alpha shape: kept tetrahedra, outward boundary, and its checks."""

    alpha: float
    keep: np.ndarray
    faces: np.ndarray            # boundary triangles, indices into complex.points
    regions: int
    voids_filled: int
    topology: MeshTopology


def alpha_shape(cx: AlphaComplex, alpha: float, fill_voids: bool = True) -> AlphaShape:
    raw = cx.radii <= alpha
    voids = cx.void_mask(raw) if fill_voids else np.zeros_like(raw)
    keep = raw | voids
    faces = cx.boundary_faces(keep)
    n_void_comp = 0
    if voids.any():
        n_void_comp = cx.count_regions(voids)
    return AlphaShape(alpha=float(alpha), keep=keep, faces=faces,
                      regions=cx.count_regions(keep), voids_filled=n_void_comp,
                      topology=mesh_topology(faces))


class AlphaShapeSurface(LimitSurface):
    """Alpha-shape GLS (paper baseline). alpha: 'paper' (median rule), 'all-points',
    'one-region', or a radius in scaled units (inf = convex hull)."""

    method = 'alpha'

    def __init__(self, n_twists: int = 2000, alpha: str | float = 'paper') -> None:
        super().__init__(n_twists)
        self.alpha = alpha

    def fit(self, problem: GLSProblem, n_twists: int | None = None) -> 'AlphaShapeSurface':
        self.problem = problem
        if n_twists is not None:
            self.n_twists = int(n_twists)
        if self.n_twists < 5:
            return self._fail_fit(Status.DEGENERATE, 'too_few_twists',
                                  f'{self.n_twists} twists: a 3D alpha shape needs >= 5 points')
        sample = sample_twists(problem.scaling, self.n_twists)
        w, why = evaluate_wrenches(problem, sample.raw)
        if w is None:
            return self._fail_fit(Status.INVALID_INPUT, 'non_finite_wrench', why)
        return self.fit_samples(problem, sample.scaled, w)

    def fit_samples(self, problem: GLSProblem, twists_scaled: np.ndarray,
                    wrenches: np.ndarray) -> 'AlphaShapeSurface':
        """Fit from paired samples: unit scaled twists (M, 3) and raw W_ext (M, 3)."""
        self.problem = problem
        ws = problem.scaling.wrench_to_scaled(np.asarray(wrenches, dtype=float))
        sv = np.linalg.svd(ws - ws.mean(axis=0), compute_uv=False)
        if len(ws) < 5 or sv[-1] < 1e-9 * sv[0]:
            return self._fail_fit(Status.DEGENERATE, 'flat_cloud',
                                  f'{len(ws)} points, singular values {np.round(sv, 6)}: no 3D '
                                  'alpha shape')
        cx = AlphaComplex(ws)
        self.complex = cx
        self._twists = np.asarray(twists_scaled, dtype=float)[cx.source_index]
        crit = cx.criteria()
        self.criteria = crit
        if isinstance(self.alpha, str):
            a = {'paper': crit.alpha_paper, 'all-points': crit.alpha_all_points,
                 'one-region': crit.alpha_one_region}[self.alpha]
        else:
            a = float(self.alpha)
        diag = {'alpha': a, 'alpha_all_points': crit.alpha_all_points,
                'alpha_one_region': crit.alpha_one_region, 'n_passing': int(len(crit.passing)),
                'n_spectrum': int(len(crit.spectrum))}
        self.fit_info = FitInfo(diagnostics=diag)
        if not np.isfinite(a) and not (np.isposinf(a) and not isinstance(self.alpha, str)):
            return self._fail_fit(Status.DEGENERATE, 'no_alpha',
                                  'no alpha gives one closed region with no voids')
        shp = alpha_shape(cx, a)
        self.shape = shp
        topo = shp.topology
        diag.update(regions=shp.regions, voids_filled=shp.voids_filled, euler=topo.euler,
                    nonmanifold_edges=topo.nonmanifold_edges, open_edges=topo.open_edges,
                    boundary_components=topo.components)
        if shp.regions != 1 or not topo.closed_genus0:
            return self._fail_fit(Status.DEGENERATE, 'alpha_topology',
                                  f'alpha {a:.4g}: {shp.regions} regions, Euler {topo.euler}, '
                                  f'{topo.nonmanifold_edges} non-manifold and {topo.open_edges} '
                                  f'open edges, {topo.components} boundary components')
        self._mesh = prepare_mesh(cx.points, shp.faces)
        wind = winding_number(cx.points, shp.faces)
        diag['winding_number'] = wind
        if abs(wind) < 0.5:
            return self._fail_fit(Status.UNSUPPORTED, 'origin_outside',
                                  f'origin outside the alpha shape (winding {wind:.3f}): the '
                                  'legs cannot hold the robot in this pose')
        self.fit_info.detail = (f'alpha {a:.4g} ({len(crit.passing)} passing of '
                                f'{len(crit.spectrum)}), {len(shp.faces)} boundary faces')
        return self

    def _capacity_many(self, ph: np.ndarray) -> list[CapacityResult]:
        d = np.stack([self.problem.load_direction_scaled(p) for p in ph])
        hits = cast_rays(self._mesh, d)
        sf = self.problem.scaling.force_N
        out = []
        for k, phi in enumerate(ph):
            f, nh = int(hits.face[k]), int(hits.n_hits[k])
            if f < 0:
                out.append(CapacityResult.make(phi, Status.DEGENERATE, self.method, None,
                                               n_hits=0, reason='no_hit',
                                               detail='ray never leaves the alpha shape'))
                continue
            tw = hits.bary[k] @ self._twists[self.shape.faces[f]]
            tw = tw / np.linalg.norm(tw)
            status, reason = Status.OK, ''
            detail = f'hits {nh}' + (' (through an edge/vertex)' if hits.on_edge[k] else '')
            if nh != 1:
                status, reason = Status.DEGENERATE, 'multiple_hits'
                detail += '; ray crosses the alpha shape more than once (first exit used)'
            out.append(CapacityResult.make(phi, status, self.method, float(hits.s[k]) * sf, tw,
                                           self.problem.scaling, n_hits=nh, reason=reason,
                                           detail=detail))
        return out
