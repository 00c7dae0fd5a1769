"""The 6D path on folded limit surfaces ("where both paths apply they agree to
1e-6"): the example anchors of examples/anchors, posed as their README documents, on the 6D
path against the sagittal reduction (an independent solver: 3D wrench space, half the facets
with doubled weights), and yawed pulls on the flat plate, whose limit surface folds."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rftgls_core.body import RigidBody, load_body_mesh
from rftgls_core.posed import (
    PosedAnchorSolver,
    mirror_plane_yaws,
    pose_robot,
    pull_plane_symmetry,
    pull_vector,
)
from rftgls_core.rft.engine import BuriedBody
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import minirquad, prototype
from rftgls_core.types import AnchorState, Pull, Status

PRESETS = {'minirquad': minirquad, 'prototype': prototype}

FOLDER = Path(__file__).resolve().parents[2] / 'examples' / 'anchors'
MEDIUM = get_medium('glass_beads')

# examples/anchors/README.md: file, mass (kg), position (m), rpy (deg), tether (m)
POSES = {
    'plate': ('plate.stl', 0.009, (0, 0, -0.08), (0, 0, 0), (0, 0, -0.08)),
    'ellipsoid': ('ellipsoid.stl', 0.040, (0, 0, -0.055), (0, 30, 0), (0, 0, -0.055)),
    'finned': ('finned.stl', 0.030, (0, 0, -0.02), (0, 0, 0), (0, 0, -0.02)),
}


@pytest.fixture(scope='module')
def posed_anchors():
    out = {}
    for name, (file, mass, pos, rpy, tether) in POSES.items():
        body = RigidBody(name, load_body_mesh(FOLDER / file, 'mm'), mass)
        out[name] = body.pose(pos, np.radians(rpy), tether)
    return out


def sagittal(posed, phi_deg, yaw_deg=0.0):
    r = PosedAnchorSolver(MEDIUM, space='sagittal', method='direct').solve(
        posed, math.radians(phi_deg), math.radians(yaw_deg))
    assert r.status is Status.OK and r.space == 'sagittal'
    return r


def six_d(posed, phi_deg, yaw_deg=0.0):
    r = PosedAnchorSolver(MEDIUM, space='6d').solve(posed, math.radians(phi_deg),
                          math.radians(yaw_deg))
    assert r.space == '6d'
    return r


@pytest.mark.parametrize('name, phi_deg', [
    ('plate', 90.0), ('plate', 60.0), ('plate', 0.0),
    ('ellipsoid', 90.0), ('ellipsoid', 45.0), ('ellipsoid', 0.0),
    ('finned', 90.0), ('finned', 30.0)])
def test_6d_equals_the_sagittal_answer_where_both_apply(posed_anchors, name, phi_deg):
    # Before the fix: plate 90 deg 5.94 N (sagittal 2.121 N), plate 60 deg and ellipsoid 45 deg
    # no_root, finned 90 deg 0.806 N (sagittal 0.724 N).
    ref = sagittal(posed_anchors[name], phi_deg)
    full = six_d(posed_anchors[name], phi_deg)
    assert full.status is Status.OK
    assert full.capacity_N == pytest.approx(ref.capacity_N, rel=1e-6)
    t6, t3 = np.array(full.slip_twist_scaled), np.array(ref.slip_twist_scaled)
    assert np.allclose(t6, t3, atol=1e-6)          # both lifted to 6D world twists


def test_the_6d_search_alone_finds_the_plates_first_exit(posed_anchors):
    # Without the in-plane candidate: the plate pulled straight up exits at the sideways slide
    # (sagittal 2.121 N, 15 crossings of the ray), a root on the switching set of the side
    # faces that free Newton cannot land on; a stalled seed short of the later roots reaches
    # it by the confined Newton. The later crossings it used to report: 5.94 N and up.
    posed = posed_anchors['plate']
    surface = PosedAnchorSolver(MEDIUM, space='6d').surface_6d(posed)
    r = surface.capacity(pull_vector(math.pi / 2))
    assert r.status is Status.OK
    assert r.capacity_N == pytest.approx(sagittal(posed, 90.0).capacity_N, rel=1e-6)
    assert np.allclose(np.array(r.slip_twist_scaled)[[1, 3, 5]], 0.0, atol=1e-6)


def test_a_yawed_vertical_pull_is_not_above_the_in_plane_exit(posed_anchors):
    # Physics: at phi = 90 deg the pull u = (0, 0, 1) does not depend on the yaw, so every yaw
    # casts the same 6D ray, and the in-plane root at yaw 0 (a planar twist whose 6D wrench
    # lies on that ray: the posed anchor is mirror-symmetric about the x-z plane) is a crossing of
    # it. The first exit can only be at or below it. Off the mirror planes the 6D search finds
    # 2.096 N, the exit on the closure of the jump across the side faces' switching set
    # (edge-on side faces between leading and trailing, 1.2 % below the RFT convention's
    # value at n . v = 0 that both paths use on the plane; the same effect as the DH pose's
    # 0.7 %, docs/design/six-d.md).
    posed = posed_anchors['plate']
    at_0 = sagittal(posed, 90.0).capacity_N
    for yaw in (5.0, 30.0, 60.0, 90.0):
        r = six_d(posed, 90.0, yaw)
        assert r.status is Status.OK
        assert r.capacity_N <= at_0 * (1.0 + 1e-6)
        assert r.capacity_N >= 0.95 * at_0        # measured 2.096 N: the bridged jump only
    # The reduction about the y-z plane (yaw 90) alone sees only slides along y: 3.39 N, above
    # the x-slide crossing of the same ray; so a vertical pull takes the least of the in-plane
    # answers over every mirror plane.
    solver = PosedAnchorSolver(MEDIUM, space='sagittal')
    yz_only = solver._solve_sagittal(posed, [math.pi / 2], math.pi / 2,
                                     pull_plane_symmetry(posed, math.pi / 2))[0]
    assert yz_only.capacity_N > 1.5 * at_0
    both = sagittal(posed, 90.0, 90.0)
    assert both.capacity_N == pytest.approx(at_0, rel=1e-12)   # the yaw-0 answer itself
    assert 'least of the in-plane answers' in both.detail
    assert six_d(posed, 90.0, 90.0).capacity_N == pytest.approx(at_0, rel=1e-6)


def test_a_slightly_yawed_pull_stays_near_the_in_plane_exit(posed_anchors):
    # phi = 80 deg, yaw 5 deg: the load direction turns by cos 80 sin 5 = 0.015 rad. Before the
    # fix the 6D path answered 6.11 N (4.3 x the 1.430 N at yaw 0, a crossing far along the
    # ray) and phi = 60 deg at yaw 5 to 75 deg was no_root. The plate is mirror-symmetric
    # about x-z (found by mirror_plane_yaws), whose in-plane slip seeds the patch search: the
    # exit on the closure of the side faces' jump, 1.408 N. Not a strict bound (a fold may
    # move the first exit far for a small turn of the ray), so the guard is measured: within
    # 5 % of yaw 0 and not above it by more than the 1e-6 the switching-set convention allows.
    posed = posed_anchors['plate']
    assert sorted(round(math.degrees(y)) for y in mirror_plane_yaws(posed)) == [0, 90]
    for phi in (80.0, 60.0):
        at_0 = sagittal(posed, phi).capacity_N
        r = six_d(posed, phi, 5.0)
        assert r.status is Status.OK and 'on_jump' in r.flags
        assert 0.95 * at_0 <= r.capacity_N <= at_0 * (1.0 + 1e-6)
    for yaw in (15.0, 30.0, 45.0, 60.0):
        assert six_d(posed, 60.0, yaw).status is Status.OK


def test_auto_is_not_above_the_6d_first_exit(posed_anchors):
    # A vertical pull lies in both of the plate's mirror planes: auto takes the least of the
    # two in-plane answers (3.39 N about the y-z plane, 2.12 N for the slide along x).
    bound = six_d(posed_anchors['plate'], 90.0, 90.0).capacity_N * (1.0 + 1e-6)
    for yaw in (math.pi / 2, 0.0):        # the pull plane is a mirror plane: sagittal
        auto = PosedAnchorSolver(MEDIUM).solve(posed_anchors['plate'], math.pi / 2, yaw)
        assert auto.space == 'sagittal' and auto.capacity_N <= bound
        assert auto.capacity_N == pytest.approx(2.1210008188, rel=1e-6)
    # Not a mirror plane: the 6D path, within its documented edge-on spread (1.2 %).
    auto = PosedAnchorSolver(MEDIUM).solve(posed_anchors['plate'], math.pi / 2, math.pi / 4)
    assert auto.space == '6d' and 0.95 * bound <= auto.capacity_N <= bound


ROBOT_STATES = {'dh': AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0),     # Table II DH
                'shallow': AnchorState.from_degrees(0.05, 0.0, -20.0, 10.0)}


@pytest.mark.parametrize('robot, state, pull, phi_deg', [
    ('minirquad', 'dh', Pull.FORWARD, 0.0), ('minirquad', 'dh', Pull.BACKWARD, -40.0),
    ('minirquad', 'shallow', Pull.FORWARD, -40.0),
    ('prototype', 'shallow', Pull.BACKWARD, -40.0),
    ('prototype', 'dh', Pull.BACKWARD, 60.0)])
def test_6d_equals_the_sagittal_answer_on_the_robots(robot, state, pull, phi_deg):
    # Here the 6D search alone ends on a gap-accepted or bridged exit 0.2 to 1.5 % below the
    # in-plane answer (the ray straddles the jump across the C-legs' edge-on sides), or the
    # sagittal answer is itself accepted 2e-4 off the ray: the in-plane answer is kept (RFT's
    # value at n . v = 0, the convention of both paths).
    posed = pose_robot(PRESETS[robot](), ROBOT_STATES[state], pull)
    med = get_medium('m90_sand')
    ref = PosedAnchorSolver(med, space='sagittal').solve(posed, math.radians(phi_deg))
    full = PosedAnchorSolver(med, space='6d').solve(posed, math.radians(phi_deg))
    assert ref.status is Status.OK and full.status is Status.OK
    assert full.capacity_N == pytest.approx(ref.capacity_N, rel=1e-6)


def test_an_exact_out_of_plane_crossing_before_the_in_plane_one_wins():
    # MiniRQuad, h 50 mm, thetaB 0, legs -20 / 10 deg, forward pull, phi 60 deg: the sagittal
    # answer is 3.7636 N; the 6D search converges (exactly) on a twist slightly out of the
    # plane (and on its mirror image) at 3.680 N, earlier on the same ray. Checked here
    # independently of the solver: the 6D wrench of the reported twist lies on the ray.
    posed = pose_robot(minirquad(), ROBOT_STATES['shallow'], Pull.FORWARD)
    med = get_medium('m90_sand')
    ref = PosedAnchorSolver(med, space='sagittal').solve(posed, math.radians(60.0))
    solver = PosedAnchorSolver(med, space='6d')
    full = solver.solve(posed, math.radians(60.0))
    assert full.status is Status.OK and 'out-of-plane crossing' in full.detail
    assert full.capacity_N < 0.99 * ref.capacity_N
    body = BuriedBody(posed.facets, solver.stress_model, ref=posed.ref)
    w = -body.wrench(np.array([full.slip_twist]))[0] - posed.gravity6()
    load = full.capacity_N * np.r_[pull_vector(math.radians(60.0)), 0.0, 0.0, 0.0]
    assert np.allclose(w, load, atol=1e-9 * full.capacity_N)
