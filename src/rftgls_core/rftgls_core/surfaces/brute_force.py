"""Brute-force reference: the first exit of the load ray from a dense twist-sphere mesh.

No root finding and no smoothing: ~10^5 twists on the sphere, their wrenches as the vertices of
the sphere's triangulation, and the first crossing of the ray with those flat triangles. A
triangle that straddles a facet switching circle spans the jump, so the dense mesh is a
polyhedral approximation of the closure of the RFT map (closure.py) with chord errors of order
(twist spacing)^2: about 1e-4 relative at 10^5 twists. Slow (a second or two per state) and
independent of the Newton and patch solvers, which is what a reference must be.
"""
from __future__ import annotations

from typing import Self

import numpy as np

from ..types import Status
from .base import CapacityResult, FitSamples, GLSProblem, LimitSurface
from .raycast import PreparedMesh, cast_rays, prepare_mesh
from .twist_sphere import TwistSphere


class BruteForceSurface(LimitSurface):
    """Dense twist-sphere mesh, first exit, no polish. n_twists: default 100,000."""

    method = 'brute-force'
    min_twists = 8

    def __init__(self, n_twists: int = 100_000) -> None:
        super().__init__(n_twists)
        self._mesh: PreparedMesh | None = None
        self._sphere: TwistSphere | None = None

    def _fit_samples(self, problem: GLSProblem, samples: FitSamples) -> Self:
        self._sphere = samples.sphere
        self._mesh = prepare_mesh(samples.wrenches_scaled, samples.sphere.faces)
        self.fit_info.detail = f'{samples.sphere.n} twists, {len(samples.sphere.faces)} faces'
        return self

    def _capacity_many(self, phis: np.ndarray) -> list[CapacityResult]:
        pr = self._fitted_problem()
        assert self._mesh is not None and self._sphere is not None
        hits = cast_rays(self._mesh, np.stack([pr.load_direction_scaled(p) for p in phis]))
        ts, faces = self._sphere.twists_scaled, self._sphere.faces
        out = []
        for k, phi in enumerate(phis):
            f = int(hits.face[k])
            if f < 0:
                out.append(CapacityResult.make(phi, Status.DEGENERATE, self.method, None,
                                               n_hits=0, reason='no_hit',
                                               detail='ray never leaves the dense mesh'))
                continue
            tw = hits.bary[k] @ ts[faces[f]]
            nh = int(hits.n_hits[k])
            out.append(CapacityResult.make(
                phi, Status.OK, self.method, float(hits.s[k]) * pr.scaling.force_N,
                tw / np.linalg.norm(tw), pr.scaling, n_hits=nh, detail=f'hits {nh}',
                flags=('multiple_crossings',) if nh > 1 else ()))
        return out
