"""First exit of a load ray through the closure of RFT's discontinuous twist -> wrench map.

RFT's wrench jumps where a facet switches between trailing (no stress) and leading (a finite
stress): for planar twists each facet switches on a great circle of the twist sphere. At the
switch itself the facet may carry any fraction lambda in [0, 1] of its leading stress, exactly
like Coulomb friction at zero slip, so the physically meaningful map is set-valued: its closure
bridges every jump with the segment between the wrenches on either side. A load ray that passes
through such a gap meets no single-valued root (Newton stalls), but it crosses the bridged gap
at a well defined point, with the slip twist on the switching circle (docs/design/closure.md).

`closure_exit` finds that crossing without knowing which facets switch: it triangulates a small
patch of the twist sphere around a seed (a 7 x 7 grid in the tangent plane, one batched
wrench evaluation), casts the ray on the patch's flat triangles, re-centres on the hit twist
and halves the patch. On a smooth part of the surface the triangles are chords whose error
falls with the square of the patch size; a triangle that straddles a switching circle has
vertices on both sides of the jump, and its plane interpolates linearly between them: the
bridged segment. So the iteration converges to the first exit of the closure in both cases,
and `bridge` (the wrench spread across the final hit triangle, relative to the distance) tells
which one it was: it vanishes on a smooth surface and stays at the jump size on a gap.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .newton import _tangent_basis, unit_rows
from .raycast import cast_rays, prepare_mesh

_K = 7
_A, _B = (g.ravel() for g in np.meshgrid(np.linspace(-1.0, 1.0, _K), np.linspace(-1.0, 1.0, _K),
                                         indexing='ij'))


def _grid_faces(k: int) -> np.ndarray:
    """Two triangles per cell of a k x k grid indexed i * k + j, alternating diagonals."""
    faces = []
    for i in range(k - 1):
        for j in range(k - 1):
            a, b, c, e = i * k + j, (i + 1) * k + j, (i + 1) * k + j + 1, i * k + j + 1
            if (i + j) % 2:
                faces += [(a, b, c), (a, c, e)]
            else:
                faces += [(a, b, e), (b, c, e)]
    return np.array(faces, dtype=np.intp)


_FACES = _grid_faces(_K)
BRIDGE_TOL = 1e-3   # relative wrench spread across the final triangle that marks a jump
SETTLED_RTOL = 1e-4  # relative spread of the last hits accepted when the patch cannot shrink


@dataclass(frozen=True)
class ClosureHit:
    """Result of `closure_exit`, in the scaled spaces.

    converged: the patch shrank below `angle_tol` with the distance settled to `rtol`, or, where
        the crossing cannot be enclosed any tighter (switching circles meeting), the last hits
        agree to SETTLED_RTOL.
    s: first-exit distance along d (scaled wrench units); nan when not converged.
    twist: (3,) unit scaled twist at the exit (on a switching circle when `bridge` is large).
    bridge: largest wrench distance between the final hit triangle's vertices over s: ~0 on a
        smooth surface, the relative jump size when the ray crosses a bridged gap.
    radius: final patch half-width, rad. levels: patches evaluated (one wrench call each).
    """

    converged: bool
    s: float
    twist: np.ndarray
    bridge: float
    radius: float
    levels: int

    @property
    def on_jump(self) -> bool:
        return self.converged and self.bridge > BRIDGE_TOL


def closure_exit(eval_scaled: Callable[[np.ndarray], np.ndarray], d: np.ndarray,
                 seed: np.ndarray, radius: float, rtol: float = 1e-7,
                 angle_tol: float = 1e-7, max_levels: int = 48) -> ClosureHit:
    """First crossing of the ray s d (s > 0) with the closure near the unit twist `seed`.

    eval_scaled: (M, 3) unit scaled twists -> (M, 3) scaled wrenches (one batched call).
    radius: initial patch half-width, rad (about the size of the coarse face that was hit).
    When the ray misses a patch (the crossing lies outside it) the patch grows, up to four
    times, before giving up.
    """
    d = np.asarray(d, dtype=float)
    t_c = unit_rows(np.asarray(seed, dtype=float).reshape(1, 3))[0]
    r = float(radius)
    r_max = min(8.0 * r, 0.5)
    found: list[float] = []       # distances of the successive patch hits
    misses = 0
    s, bridge, level = np.nan, np.nan, 0
    for level in range(1, max_levels + 1):
        u, v = _tangent_basis(t_c[None, :])
        pts = unit_rows(t_c + r * (_A[:, None] * u + _B[:, None] * v))
        ws = eval_scaled(pts)
        hits = cast_rays(prepare_mesh(ws, _FACES), d)
        f = int(hits.face[0])
        if f < 0 or not np.isfinite(hits.s[0]):
            # The crossing left the patch. Where several switching circles meet (a staircase
            # of small jumps) a re-centred half patch can straddle it without covering it: the
            # hits have then settled already, to SETTLED_RTOL.
            misses += 1
            if len(found) >= 3 and np.ptp(found[-3:]) <= SETTLED_RTOL * found[-1]:
                return ClosureHit(True, found[-1], t_c, bridge, r, level)
            if misses > 12 or r >= r_max:
                break
            r = min(2.0 * r, r_max)
            continue
        tri = _FACES[f]
        s = float(hits.s[0])
        t_c = unit_rows((hits.bary[0] @ pts[tri])[None, :])[0]
        w = ws[tri]
        bridge = float(max(np.linalg.norm(w[0] - w[1]), np.linalg.norm(w[1] - w[2]),
                           np.linalg.norm(w[0] - w[2]))) / max(s, 1e-300)
        # (at a jump s settles like the patch size: 1e-7 rad moves it by ~1e-7 relative)
        if r <= angle_tol and found and abs(s - found[-1]) <= rtol * max(s, 1e-300):
            return ClosureHit(True, s, t_c, bridge, r, level)
        found.append(s)
        r *= 0.5
    return ClosureHit(False, np.nan, t_c, bridge, r, level)


_K_FOLD = 13
_AF, _BF = (g.ravel() for g in np.meshgrid(np.linspace(-1.0, 1.0, _K_FOLD),
                                           np.linspace(-1.0, 1.0, _K_FOLD), indexing='ij'))
_FACES_FOLD = _grid_faces(_K_FOLD)
# The fold patches: the full radius and 0.6 of it (spacing ~0.042 and ~0.025 rad at 0.25 rad),
# each at three grid orientations, evaluated in one call. A fold sheet narrower than the spacing is
# crossed by the ray only where a patch's triangles happen to straddle it: MiniRQuad at h =
# 41.1 mm, thetaB = 0.77, thetaL1 = -47.4, thetaL2 = 19.6 deg, backward, phi = -20.2 deg has a
# sheet ~0.03 rad wide 9 deg from the root (1.432 N against 1.781 N), which the 0.25 rad
# patch missed and the 0.15 rad ones see at two of three orientations.
_FOLD_SCALES = (1.0, 0.6)
_FOLD_TURNS = (0.0, 0.61, 1.23)   # rad
_FOLD_PATCHES = len(_FOLD_SCALES) * len(_FOLD_TURNS)


def _fold_coefficients() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangent-plane coordinates (along u, along v) of every fold-patch twist per unit radius,
    and each patch's scale."""
    cu, cv = [], []
    for k in _FOLD_SCALES:
        for a in _FOLD_TURNS:
            c, s = np.cos(a), np.sin(a)
            cu.append(k * (c * _AF - s * _BF))
            cv.append(k * (s * _AF + c * _BF))
    scales = np.repeat(np.asarray(_FOLD_SCALES), len(_FOLD_TURNS))
    return np.concatenate(cu), np.concatenate(cv), scales


_FU, _FV, _FOLD_SCALE_OF = _fold_coefficients()
_FOLD_SAME_RAD = 0.02   # crossings this close (and at the same distance) are one sheet
# Where a solver's answer lies this far (relative) from its mesh chord, the surface may fold
# there and `earlier_exit` runs: twist-mesh (1,000-twist chords) from 1 %; direct (400-twist
# chords, further from its roots as a rule, and the warm step, which mirrors it at 0.8 of it,
# must stay under a millisecond on a stream) from 3 %.
FOLD_CHECK_RTOL = 0.01
DIRECT_FOLD_CHECK_RTOL = 0.03


def earlier_exit(eval_scaled: Callable[[np.ndarray], np.ndarray], d: np.ndarray,
                 twist: np.ndarray, s: float, radius: float = 0.25,
                 angle_tol: float = 1e-7, max_rounds: int = 3) -> ClosureHit | None:
    """An exit closer than `s` near `twist`, on a fold sheet too thin for the coarse mesh.

    RFT surfaces fold, and a sheet thinner than the bracketing sphere's spacing is invisible to
    it: the solver then reports the next crossing, too far out. Run where a fold is suspected
    (several roots, or a polish that moved far from the chord): dense 13 x 13 patches around
    the answer, of half-width `radius` rad and 0.6 of it (spacing ~0.042 and ~0.025 rad), each
    at three grid orientations, in one wrench call; where the ray crosses a patch closer than
    s, the closure search follows that crossing (every patch's, nearest first; the nearest
    converged exit wins), and the patches are laid again around the new exit (up to
    `max_rounds` times). None when there is no earlier exit.
    """
    best: ClosureHit | None = None
    # The patch's first crossing is the nearest *chord*, and the closure search from it can
    # settle on a sheet that is itself not the first: the prototype at h = 29.3 mm, thetaL2 =
    # -32.6 deg, backward, phi = -21.1 deg went 2.346 -> 2.162 N in one round, while the exit
    # (direct, the refined brute force) is 2.018 N, found by a second round from 2.162 N.
    for _ in range(max_rounds):
        t0 = unit_rows(np.asarray(twist, dtype=float).reshape(1, 3))[0]
        u, v = _tangent_basis(t0[None, :])
        pts = unit_rows(t0 + radius * (_FU[:, None] * u + _FV[:, None] * v))
        ws = eval_scaled(pts)
        # Each patch's first crossing in front of s seeds a closure search, nearest first,
        # and the nearest converged exit wins: the search from one patch's crossing can fail
        # or settle further out where another's finds the sheet, so no patch hides another.
        n = _K_FOLD ** 2
        seeds = []
        for k in range(_FOLD_PATCHES):
            hits = cast_rays(prepare_mesh(ws[k * n:(k + 1) * n], _FACES_FOLD), d)
            f = int(hits.face[0])
            if f >= 0 and hits.s[0] < s * (1.0 - 1e-4):
                seeds.append((float(hits.s[0]), k, hits.bary[0] @ pts[k * n + _FACES_FOLD[f]]))
        found: ClosureHit | None = None
        tried: list[tuple[float, np.ndarray]] = []
        for s_k, k, seed in sorted(seeds, key=lambda x: x[:2]):
            seed = unit_rows(seed[None, :])[0]
            # a crossing at the same distance and place as one already followed is the same
            # sheet (patches of different orientation crossing it side by side)
            if any(abs(s_k - s_j) <= 1e-3 * s and float(seed @ t_j) > math.cos(_FOLD_SAME_RAD)
                   for s_j, t_j in tried):
                continue
            tried.append((s_k, seed))
            ch = closure_exit(eval_scaled, d, seed,
                              2.0 * radius * float(_FOLD_SCALE_OF[k]) / (_K_FOLD - 1),
                              angle_tol=angle_tol)
            if ch.converged and ch.s < s * (1.0 - 1e-6) and (found is None or ch.s < found.s):
                found = ch
        if found is None:
            break
        best, twist, s = found, found.twist, found.s
    return best


# The local check after a converged root: three 9 x 9 patches of different sizes and grid
# orientations, one wrench call. A jump next to the root can leave a sliver of the closure in
# front of it whose width is below the patch spacing; whether a grid's triangles straddle it
# depends on the grid's alignment, so the patches are turned against each other.
_K_LOCAL = 9
_LOCAL_RADII = (0.004, 0.01, 0.025)
_LOCAL_TURNS = (0.0, 0.61, 1.23)   # rad, patch grid orientations in the tangent plane
_FACES_LOCAL = _grid_faces(_K_LOCAL)
_AL, _BL = (g.ravel() for g in np.meshgrid(np.linspace(-1.0, 1.0, _K_LOCAL),
                                           np.linspace(-1.0, 1.0, _K_LOCAL), indexing='ij'))
# the three patches as one mesh (cast once: its first hit is the nearest patch crossing)
_FACES_LOCAL_ALL = np.concatenate([_FACES_LOCAL + k * _K_LOCAL ** 2
                                   for k in range(len(_LOCAL_RADII))])
LOCAL_RTOL = 1e-3   # a patch crossing this far in front of the root is followed


def _local_coefficients() -> tuple[np.ndarray, np.ndarray]:
    """Tangent-plane coordinates (along u, along v) of every patch twist, rad."""
    cu, cv = [], []
    for r, a in zip(_LOCAL_RADII, _LOCAL_TURNS):
        c, s = np.cos(a), np.sin(a)
        # r (A (c u + s v) + B (-s u + c v))
        cu.append(r * (c * _AL - s * _BL))
        cv.append(r * (s * _AL + c * _BL))
    return np.concatenate(cu), np.concatenate(cv)


_CU, _CV = _local_coefficients()


def local_patches(twist: np.ndarray) -> np.ndarray:
    """The twists (3 * 81, 3) of `local_exit`'s patches around the unit twist `twist`."""
    t0 = unit_rows(np.asarray(twist, dtype=float).reshape(1, 3))[0]
    u, v = _tangent_basis(t0[None, :])
    return unit_rows(t0 + _CU[:, None] * u + _CV[:, None] * v)


def local_exit(eval_scaled: Callable[[np.ndarray], np.ndarray], d: np.ndarray,
               twist: np.ndarray, s: float, angle_tol: float = 1e-7) -> ClosureHit | None:
    """An exit of the closure closer than the converged root `s` within a few degrees of it.

    Newton converges to a smooth root even where the ray crosses a bridged jump just in front
    of it (prototype, seed 12 of `rftgls chart agreement`: a root at 0.0222 N, the closure exit
    0.3 deg away at 0.0125 N). The patches of `local_patches` (one wrench call) are triangulated
    like the closure search's and cast; a crossing more than LOCAL_RTOL in front of the root
    seeds `closure_exit`, whose converged exit replaces the root when it is closer. None when
    no patch crosses in front of the root.
    """
    pts = local_patches(twist)
    hits = cast_rays(prepare_mesh(eval_scaled(pts), _FACES_LOCAL_ALL), d)
    f = int(hits.face[0])
    if f < 0 or not hits.s[0] < s * (1.0 - LOCAL_RTOL):
        return None
    r = _LOCAL_RADII[f // len(_FACES_LOCAL)]
    seed = hits.bary[0] @ pts[_FACES_LOCAL_ALL[f]]
    ch = closure_exit(eval_scaled, d, seed, 2.0 * r / (_K_LOCAL - 1), angle_tol=angle_tol)
    return ch if ch.converged and ch.s < s * (1.0 - 1e-5) else None


# The check around an exit the closure search found (Newton failed there: a jump, or a
# staircase of small jumps). Where switching circles lie a few 1e-4 rad apart, the closure is
# locally folded and the search may settle on a crossing that is not the first: the prototype
# at h = 28.8 mm, thetaB = -5.8, thetaL1 = 39.3, thetaL2 = -29.4 deg, forward, phi = -26.6 deg
# settled on a jump at 0.538 N while a smooth root 0.0017 rad away maps onto the ray at
# 0.526 N (the refined brute force; the wrench there is on the ray to 1e-15). The patches of
# `local_exit` (spacing >= 1e-3 rad) straddle several jumps and miss it; 13 x 13 patches of
# half-width 0.001-0.004 rad (spacing down to 1.7e-4 rad) find it at every grid turn tried.
_K_FINE = 13
_FINE_RADII = (0.001, 0.002, 0.004)
_FINE_TURNS = (0.0, 0.61, 1.23)


def _patch_coefficients(k: int, radii: tuple[float, ...], turns: tuple[float, ...]
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Tangent-plane coordinates (along u, along v), rad, of k x k patches, one per radius."""
    g = np.linspace(-1.0, 1.0, k)
    a, b = (x.ravel() for x in np.meshgrid(g, g, indexing='ij'))
    cu = [r * (np.cos(t) * a - np.sin(t) * b) for r, t in zip(radii, turns)]
    cv = [r * (np.sin(t) * a + np.cos(t) * b) for r, t in zip(radii, turns)]
    return np.concatenate(cu), np.concatenate(cv)


_JUMP_PATCHES = ([(_K_FINE, r) for r in _FINE_RADII]
                 + [(_K_LOCAL, r) for r in _LOCAL_RADII])
_CU_J, _CV_J = (np.concatenate(x) for x in zip(
    _patch_coefficients(_K_FINE, _FINE_RADII, _FINE_TURNS),
    _patch_coefficients(_K_LOCAL, _LOCAL_RADII, _LOCAL_TURNS)))
_FACES_J_PARTS = []
_offset = 0
for _k, _r in _JUMP_PATCHES:
    _FACES_J_PARTS.append(_grid_faces(_k) + _offset)
    _offset += _k * _k
_FACES_JUMP = np.concatenate(_FACES_J_PARTS)
# the patch each face belongs to, and that patch's grid spacing (rad)
_JUMP_FACE_SPACING = np.concatenate([np.full(len(_grid_faces(k)), 2.0 * r / (k - 1))
                                     for k, r in _JUMP_PATCHES])
JUMP_CHECK_ROUNDS = 3


def jump_exit(eval_scaled: Callable[[np.ndarray], np.ndarray], d: np.ndarray,
              twist: np.ndarray, s: float, angle_tol: float = 1e-7,
              max_rounds: int = JUMP_CHECK_ROUNDS) -> ClosureHit | None:
    """An exit of the closure closer than `s`, next to an exit found by the closure search.

    Like `local_exit`, with three finer 13 x 13 patches (half-widths 0.001, 0.002, 0.004 rad,
    turned against each other) next to its three (one wrench call, 750 twists). A crossing more
    than LOCAL_RTOL in front of `s` seeds `closure_exit`; a closer converged exit replaces the
    answer, and the patches are laid again around it (up to `max_rounds` times). None when no
    round finds a closer exit.
    """
    best: ClosureHit | None = None
    for _ in range(max_rounds):
        t0 = unit_rows(np.asarray(twist, dtype=float).reshape(1, 3))[0]
        u, v = _tangent_basis(t0[None, :])
        pts = unit_rows(t0 + _CU_J[:, None] * u + _CV_J[:, None] * v)
        hits = cast_rays(prepare_mesh(eval_scaled(pts), _FACES_JUMP), d)
        f = int(hits.face[0])
        if f < 0 or not hits.s[0] < s * (1.0 - LOCAL_RTOL):
            break
        seed = hits.bary[0] @ pts[_FACES_JUMP[f]]
        ch = closure_exit(eval_scaled, d, seed, float(_JUMP_FACE_SPACING[f]),
                          angle_tol=angle_tol)
        if not (ch.converged and ch.s < s * (1.0 - 1e-5)):
            break
        best, twist, s = ch, ch.twist, ch.s
    return best
