"""The posed anchor: any buried body, any tether direction, in the sagittal reduction or in 6D.

A PosedAnchor is the body in sand that a capacity needs, whoever posed it (a robot from its
state, an anchor description from its state values, a rigid body from an STL): world-frame
facets, the tether point p (reference of twists and moments), mass and centre of mass, and a
characteristic length for the scaled metric. The tether pulls p along

    u(phi, yaw) = Rz(yaw) (-cos phi, 0, sin phi)     (world; phi = 90 deg pulls straight up)

PosedAnchorSolver answers its capacity. "Model no more than the anchor needs, and no less"
(docs/design/six-d.md): when the buried facets and the centre of mass are mirror-symmetric
about the pull plane (the vertical plane through p that contains u), planar twists in that
plane map to planar wrenches and the sagittal reduction of surfaces/ (3D wrench space, one half
of the facets with doubled weights) answers. The symmetry is checked on the facets themselves,
never assumed. Otherwise the full 6D path of gls6d.py answers.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .geometry.mesh import Facets
from .geometry.transforms import rot_z
from .gls6d import DEFAULT_TWISTS_6D, EARLIER_ANGLE, InPlane6, Problem6, Result6, Scaling6, Surface6
from .rft.engine import BuriedBody
from .rft.media import Medium
from .rft.models import make_model
from .robots.robot import G, Robot
from .surfaces.base import GLSProblem
from .surfaces.registry import default_twists, surface_class
from .surfaces.scaling import Scaling
from .types import AnchorState, Pull, Status

SPACES = ('auto', 'sagittal', '6d')
# Facet symmetry tolerance, relative to the anchor's characteristic length: STL files store
# float32 coordinates (about 6e-8 relative), CAD exports a little worse.
SYMMETRY_RTOL = 1e-6


@dataclass(frozen=True)
class PosedAnchor:
    """A posed body in the medium (SI, world frame W: z up, free surface z = 0).

    facets: world facets of everything that may touch the medium. ref: the tether point p, m.
    mass: kg. com: centre of mass, m (world). char_length: L_c of the scaled metric, m.
    """

    name: str
    facets: Facets
    ref: np.ndarray
    mass: float
    com: np.ndarray
    char_length: float
    notes: dict = field(default_factory=dict, compare=False)

    @property
    def weight(self) -> float:
        return self.mass * G

    def gravity6(self) -> np.ndarray:
        """Gravity wrench (Fx, Fy, Fz, Mx, My, Mz) about p, N and N m."""
        f = np.array([0.0, 0.0, -self.weight])
        return np.r_[f, np.cross(np.asarray(self.com) - self.ref, f)]

    def buried(self) -> Facets:
        return self.facets.subset(self.facets.centroids[:, 2] < 0.0)


def pull_vector(phi: float, yaw: float = 0.0) -> np.ndarray:
    """Unit tether direction u(phi, yaw) in the world (rad)."""
    return rot_z(yaw) @ np.array([-math.cos(phi), 0.0, math.sin(phi)])


def pose_robot(robot: Robot, state: AnchorState, pull: Pull | str) -> PosedAnchor:
    """The sagittal robot as a PosedAnchor (both sides of its legs, p as the tether point)."""
    posed = robot.pose(state, pull)
    p = np.asarray(posed.ref, dtype=float)
    c, s = math.cos(state.theta_b), math.sin(state.theta_b)
    # Body x_B tilts up by thetaB (robots/robot.py: rot_y(-thetaB)).
    com = p + np.array([c * robot.com[0] - s * robot.com[1], 0.0,
                        s * robot.com[0] + c * robot.com[1]])
    return PosedAnchor(name=robot.name, facets=posed.facets, ref=p, mass=robot.mass, com=com,
                       char_length=robot.char_length)


@dataclass(frozen=True)
class Symmetry:
    """Whether a posed anchor is mirror-symmetric about its pull plane, and why not."""

    symmetric: bool
    detail: str


def pull_plane_symmetry(posed: PosedAnchor, yaw: float, rtol: float = SYMMETRY_RTOL) -> Symmetry:
    """Check (not assume) the mirror symmetry about the vertical plane through p with normal
    Rz(yaw) y: every buried facet must have a mirror facet (centroid, normal, area) and the
    centre of mass must lie in the plane. Facets above the surface carry no force."""
    n = rot_z(yaw) @ np.array([0.0, 1.0, 0.0])
    tol = rtol * max(posed.char_length, 1e-12)
    off = float(np.dot(np.asarray(posed.com) - posed.ref, n))
    if abs(off) > tol:
        return Symmetry(False, f'centre of mass {off * 1e3:.3g} mm off the pull plane')
    f = posed.buried()
    if len(f) == 0:
        return Symmetry(True, 'nothing buried')
    rel = f.centroids - posed.ref
    mirrored = f.centroids - 2.0 * np.outer(rel @ n, n)
    mnorm = f.normals - 2.0 * np.outer(f.normals @ n, n)
    dist, idx = cKDTree(f.centroids).query(mirrored, k=1)
    bad = ((dist > tol) | (np.linalg.norm(f.normals[idx] - mnorm, axis=1) > 1e3 * rtol)
           | (np.abs(f.areas[idx] - f.areas) > 1e3 * rtol * np.maximum(f.areas, 1e-300)))
    if np.any(bad):
        return Symmetry(False, f'{int(bad.sum())} of {len(f)} buried facets have no mirror '
                               f'image about the pull plane (yaw {math.degrees(yaw):.3g} deg)')
    return Symmetry(True, f'all {len(f)} buried facets and the centre of mass are mirror-'
                          f'symmetric about the pull plane (yaw {math.degrees(yaw):.3g} deg)')


def mirror_planes(posed: PosedAnchor) -> list[tuple[float, Symmetry]]:
    """The vertical planes through p about which the posed anchor is mirror-symmetric: (yaw in
    [0, pi) of the plane with normal Rz(yaw) y, its passed `pull_plane_symmetry` check).
    Candidates: the principal axes of the buried facets' horizontal area moment about p (a
    mirror plane's normal is one of them, as the moment is invariant under the mirror) and the
    world x and y axes (when the moment is isotropic, e.g. a cross of fins, its axes are
    arbitrary)."""
    f = posed.buried()
    if len(f) == 0:
        return []
    rel = (f.centroids - posed.ref)[:, :2]
    mom = (rel * f.areas[:, None]).T @ rel
    _, vec = np.linalg.eigh(mom)
    cands = [math.atan2(-float(v[0]), float(v[1])) for v in vec.T] + [0.0, math.pi / 2]
    out: list[tuple[float, Symmetry]] = []
    for c in cands:
        c = c % math.pi     # the plane with normal Rz(c) y
        if any(abs(math.remainder(c - o, math.pi)) < 1e-9 for o, _ in out):
            continue
        sym = pull_plane_symmetry(posed, c)
        if sym.symmetric:
            out.append((c, sym))
    return out


def mirror_plane_yaws(posed: PosedAnchor) -> list[float]:
    """The yaws (rad, in [0, pi)) of `mirror_planes`."""
    return [yaw for yaw, _ in mirror_planes(posed)]


@dataclass(frozen=True)
class PosedAnchorResult:
    """Capacity along u(phi, yaw) and the slip twist, always as 6D world quantities.

    slip_twist: the slip twist (vx, vy, vz, wx, wy, wz) of the tether point, world axes, m/s and
    rad/s, unit Euclidean norm; slip_twist_scaled: the same direction as a unit vector
    (vx, vy, vz, wx L_c, wy L_c, wz L_c). space: 'sagittal' or '6d' (which path answered).
    """

    status: Status
    method: str
    space: str
    capacity_N: float | None = None
    slip_twist: tuple[float, ...] | None = None
    slip_twist_scaled: tuple[float, ...] | None = None
    reason: str = ''
    detail: str = ''
    flags: tuple[str, ...] = ()
    twist_spread_rad: float | None = None

    @property
    def ok(self) -> bool:
        return self.status.has_value


class PosedAnchorSolver:
    """Capacity of a PosedAnchor for a tether angle and yaw, on the smallest model that is exact.

    space: 'auto' (sagittal when the symmetry check passes, else 6D), 'sagittal' (refused with
    `invalid_input` `not_symmetric` when the check fails) or '6d' (always the full path).
    method / n_twists: the sagittal limit-surface method; the 6D path is `direct` in 6D with
    n_twists_6d bracketing twists.
    """

    def __init__(self, medium: Medium, model: str = 'agarwal', method: str = 'direct',
                 n_twists: int | None = None, space: str = 'auto',
                 n_twists_6d: int = DEFAULT_TWISTS_6D, backend: str = 'auto'):
        if space not in SPACES:
            raise ValueError(f'space must be one of {", ".join(SPACES)}, got {space!r}')
        self.medium = medium
        self.stress_model = make_model(model, medium)
        self.method = method
        self.surface_cls = surface_class(method)
        self.n_twists = int(n_twists if n_twists is not None else default_twists(method))
        self.space = space
        self.n_twists_6d = int(n_twists_6d)
        self.backend = backend

    @staticmethod
    def scaling_for(posed: PosedAnchor) -> tuple[float, float]:
        # s_F = the weight (as for the robots); a weightless body gets 1 N (only a unit).
        return (posed.weight if posed.weight > 0.0 else 1.0), posed.char_length

    def solve(self, posed: PosedAnchor, phi: float, yaw: float = 0.0) -> PosedAnchorResult:
        """Capacity of `posed` along u(phi, yaw) (rad) and its slip twist."""
        return self.solve_many(posed, [phi], yaw)[0]

    def solve_many(self, posed: PosedAnchor, phis, yaw: float = 0.0
                   ) -> list[PosedAnchorResult]:
        """`solve` at several tether angles (rad) of one posed anchor and yaw: the limit
        surface is fitted once and asked along every u(phi, yaw) (a map node's angles), with
        the answers `solve` gives one by one (the fit does not depend on phi)."""
        phis = [float(x) for x in np.atleast_1d(np.asarray(phis, dtype=float))]
        bad = [p for p in phis if not math.isfinite(p)]
        if bad or not math.isfinite(yaw):
            def invalid(phi: float) -> PosedAnchorResult:
                return PosedAnchorResult(Status.INVALID_INPUT, self.method, self.space,
                                         reason='invalid_phi', detail=f'phi {phi!r}, yaw {yaw!r}')
            if not math.isfinite(yaw):
                return [invalid(p) for p in phis]
            good = [p for p in phis if math.isfinite(p)]
            answers = iter(self.solve_many(posed, good, yaw) if good else [])
            return [next(answers) if math.isfinite(p) else invalid(p) for p in phis]
        if len(posed.buried()) == 0:
            return [PosedAnchorResult(Status.UNSUPPORTED, self.method, self.space,
                                      reason='no_buried_facet',
                                      detail='no facet of the body is below the free surface z = 0')
                    for _ in phis]
        sym = pull_plane_symmetry(posed, yaw)
        if self.space == 'sagittal' and not sym.symmetric:
            return [PosedAnchorResult(Status.INVALID_INPUT, self.method, 'sagittal',
                                      reason='not_symmetric',
                                      detail='the sagittal reduction needs mirror symmetry '
                                             'about the pull plane: ' + sym.detail)
                    for _ in phis]
        if self.space == '6d' or not sym.symmetric:
            return self._solve_6d(posed, phis, yaw, sym)
        out = self._solve_sagittal(posed, phis, yaw, sym)
        vertical = [k for k, phi in enumerate(phis) if abs(math.cos(phi)) < 1e-12]
        if vertical:
            self._least_over_mirror_planes(posed, phis, yaw, vertical, out)
        return out

    def _least_over_mirror_planes(self, posed: PosedAnchor, phis: list[float], yaw: float,
                                  vertical: list[int], out: list[PosedAnchorResult]) -> None:
        """A vertical pull lies in every vertical plane: each mirror plane of the body gives
        an in-plane crossing of the same load ray, and the sagittal reduction in one plane cannot
        see the others' (a flat plate pulled up slides along its long side, out of the plane of
        its short side). The first exit is the least of them (in place, for the indices
        `vertical`)."""
        for plane, plane_sym in mirror_planes(posed):
            if abs(math.remainder(plane - yaw, math.pi)) < 1e-9:
                continue
            other = self._solve_sagittal(posed, [phis[k] for k in vertical], plane,
                                           plane_sym)
            for k, res in zip(vertical, other):
                cur = out[k]
                if res.capacity_N is not None and (cur.capacity_N is None
                                                   or res.capacity_N < cur.capacity_N):
                    out[k] = dataclasses.replace(
                        res, detail=f'vertical pull: the least of the in-plane answers over '
                                    f'the mirror planes (this one at yaw '
                                    f'{math.degrees(plane):.3g} deg); ' + res.detail)

    # -- the sagittal reduction ------------------------------------------------------------
    def _solve_sagittal(self, posed: PosedAnchor, phis: list[float], yaw: float,
                          sym: Symmetry) -> list[PosedAnchorResult]:
        p = np.asarray(posed.ref, dtype=float)
        facets = posed.facets
        com = np.asarray(posed.com, dtype=float)
        if yaw != 0.0:   # turn the pull plane into the x-z plane through p
            r = rot_z(-yaw)
            facets = Facets((facets.centroids - p) @ r.T + p, facets.normals @ r.T,
                            facets.areas)
            com = r @ (com - p) + p
        body = BuriedBody(facets, self.stress_model, ref=p, mirror_y=float(p[1]),
                          backend=self.backend)
        w = posed.weight
        gravity = np.array([0.0, -w, w * (com[0] - p[0])])

        def wrench_fn(twists: np.ndarray) -> np.ndarray:
            return -body.planar_wrench(twists) - gravity

        sf, lc = self.scaling_for(posed)
        surface = self.surface_cls(n_twists=self.n_twists).fit(
            GLSProblem(wrench_fn, Scaling(sf, lc)))
        rz = rot_z(yaw)

        def lift(t3) -> tuple[float, ...]:
            v = rz @ np.array([t3[0], 0.0, t3[1]])
            om = rz @ np.array([0.0, t3[2], 0.0])
            return tuple(float(x) for x in np.r_[v, om])
        out = []
        for phi in phis:
            res = surface.capacity(phi)
            twist = scaled = None
            if res.slip_twist_scaled is not None and res.slip_twist is not None:
                twist, scaled = lift(res.slip_twist), lift(res.slip_twist_scaled)
            out.append(PosedAnchorResult(res.status, res.method, 'sagittal', res.capacity_N, twist,
                                         scaled, res.reason,
                                         'sagittal reduction: ' + sym.detail + '; ' + res.detail,
                                         res.flags, res.twist_spread_rad))
        return out

    # -- the full 6D path --------------------------------------------------------------------
    def surface_6d(self, posed: PosedAnchor) -> Surface6:
        body = BuriedBody(posed.facets, self.stress_model, ref=posed.ref, backend=self.backend)
        g = posed.gravity6()

        def wrench_fn(twists: np.ndarray) -> np.ndarray:
            return -body.wrench(twists) - g

        sf, lc = self.scaling_for(posed)
        f = posed.buried()
        forms = np.hstack([f.normals, np.cross(f.centroids - posed.ref, f.normals)])
        return Surface6(n_twists=self.n_twists_6d).fit(
            Problem6(wrench_fn, g, Scaling6(sf, lc), switch_forms=forms))

    def _solve_6d(self, posed: PosedAnchor, phis: list[float], yaw: float,
                    sym: Symmetry) -> list[PosedAnchorResult]:
        surface = self.surface_6d(posed)
        why = ('6D forced (--space 6d)' if sym.symmetric else 'full 6D: ' + sym.detail)
        # Mirror-symmetric about the pull plane: the in-plane answer is a crossing of the 6D
        # ray too (docs/design/six-d.md), one the cloud's seeds can miss (a root on a switching
        # set, a fold); the 6D search keeps it as a candidate and looks for earlier ones.
        planar: list[InPlane6 | None] = [None] * len(phis)
        if sym.symmetric:
            nx, ny, nz = (float(v) for v in rot_z(yaw) @ np.array([0.0, 1.0, 0.0]))
            normal = (nx, ny, nz)
            planar = [InPlane6(r.capacity_N, r.slip_twist_scaled, r.flags, normal)
                      if r.ok and r.capacity_N is not None and r.slip_twist_scaled is not None
                      else None for r in self._solve_sagittal(posed, phis, yaw, sym)]
        # Not symmetric about the pull plane but about another vertical plane through p (a
        # yawed pull on a symmetric body): the in-plane answers there, lifted, seed the 6D
        # search. A pull yawed slightly off a mirror plane often exits near that plane's slip
        # (on the closure of the jump across it), where the cloud's seeds do not reach.
        # Only a plane whose pull lies within EARLIER_ANGLE of the actual one (the reach of the
        # earlier-crossing seeds) is solved: farther off, its slip says little about this ray.
        seeds: list[list[np.ndarray]] = [[] for _ in phis]
        if not sym.symmetric:
            for plane_yaw in mirror_plane_yaws(posed):
                # the sense of the plane's pull nearer to the actual yaw
                near = plane_yaw + math.pi * round((yaw - plane_yaw) / math.pi)
                close = [float(pull_vector(p, yaw) @ pull_vector(p, near))
                         > math.cos(EARLIER_ANGLE) for p in phis]
                if not any(close):
                    continue
                for k, r0 in enumerate(self._solve_sagittal(posed, phis, near, Symmetry(
                        True, 'mirror plane'))):
                    if close[k] and r0.ok and r0.slip_twist_scaled is not None:
                        seeds[k].append(np.asarray(r0.slip_twist_scaled, dtype=float))
        out = []
        for phi, cand, sd in zip(phis, planar, seeds, strict=True):
            r: Result6 = surface.capacity(pull_vector(phi, yaw), in_plane=cand,
                                          seeds=np.array(sd) if sd else None)
            out.append(PosedAnchorResult(r.status, r.method, '6d', r.capacity_N, r.slip_twist,
                                         r.slip_twist_scaled, r.reason, why + '; ' + r.detail,
                                         r.flags))
        return out
