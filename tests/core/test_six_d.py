"""The 6D path (gls6d.py, posed.py): exact on a synthetic 6D surface, equal to the sagittal
reduction where both apply, out of the plane where the pull is."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.gls6d import Problem6, Scaling6, Surface6, complement_basis, sphere5
from rftgls_core.posed import PosedAnchorSolver, pose_robot, pull_plane_symmetry, pull_vector
from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import minirquad
from rftgls_core.types import AnchorState, Pull, Status

DH = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)   # paper Table II, the DH anchor


def test_sphere5_and_complement_basis_are_orthonormal():
    s = sphere5(500)
    assert s.shape == (500, 6) and np.allclose(np.linalg.norm(s, axis=1), 1.0)
    d = s[7]
    b = complement_basis(d)
    assert np.allclose(b @ b.T, np.eye(5)) and np.allclose(b @ d, 0.0)


def test_capacity_on_an_exact_6d_ellipsoid():
    # Dissipation D(t) = |A t| gives W(t) = A^T A t / |A t|: every wrench lies on the ellipsoid
    # |A^-T W| = 1, so the exit along d is at s = 1 / |A^-T d| (exact, no RFT involved), and the
    # twist there is A^-1 A^-T d up to scale. A shift by -g puts the origin off-centre.
    rng = np.random.default_rng(3)
    a = np.diag([3.0, 5.0, 4.0, 0.05, 0.08, 0.06]) + 0.01 * rng.normal(size=(6, 6))
    g = np.array([0.0, 0.0, -1.0, 0.01, 0.0, 0.0])

    def wrench_fn(t):
        at = t @ a.T
        return at @ a / np.linalg.norm(at, axis=1, keepdims=True) - g

    surf = Surface6().fit(Problem6(wrench_fn, g, Scaling6(1.0, 0.02)))
    assert surf.fit_status is Status.OK
    ainv_t = np.linalg.inv(a.T)
    for u in (np.array([-1.0, 0, 0]), pull_vector(math.radians(40), math.radians(25))):
        r = surf.capacity(u)
        d = np.r_[u, 0, 0, 0]
        # s along d with W_ext = W_0 - g: solve |A^-T (s d + g)| = 1 for s > 0 (a quadratic).
        p, q = ainv_t @ d, ainv_t @ g
        s_exact = (-(p @ q) + math.sqrt((p @ q) ** 2 - (p @ p) * (q @ q - 1.0))) / (p @ p)
        assert r.status is Status.OK and r.capacity_N == pytest.approx(s_exact, rel=1e-9)
        twist = np.linalg.solve(a, ainv_t @ (s_exact * d + g))
        raw = np.array(r.slip_twist)
        assert abs(raw @ twist) / np.linalg.norm(twist) == pytest.approx(1.0, abs=1e-8)


def test_a_weight_beyond_the_surface_is_unsupported():
    def wrench_fn(t):
        return t / np.linalg.norm(t, axis=1, keepdims=True) - g
    g = np.array([0.0, 0.0, -2.0, 0.0, 0.0, 0.0])        # the unit ball cannot hold 2
    surf = Surface6().fit(Problem6(wrench_fn, g, Scaling6(1.0, 1.0)))
    assert surf.capacity(np.array([0.0, 0.0, 1.0])).status is Status.UNSUPPORTED


@pytest.fixture(scope='module')
def dh_posed():
    return pose_robot(minirquad(), DH, Pull.BACKWARD)


@pytest.mark.parametrize('phi_deg', [0.0, -20.0, 30.0])
def test_6d_equals_the_sagittal_answer_at_yaw_0(dh_posed, phi_deg):
    sagittal = RobotPredictor(minirquad(), get_medium('m90_sand'), method='direct').predict(
        DH, math.radians(phi_deg), Pull.BACKWARD)
    full = PosedAnchorSolver(get_medium('m90_sand'), space='6d').solve(dh_posed,
                             math.radians(phi_deg))
    assert full.space == '6d' and full.status is Status.OK
    assert full.capacity_N == pytest.approx(sagittal.capacity_N, rel=1e-6)
    t6 = np.array(full.slip_twist_scaled)
    t3 = np.array(sagittal.slip_twist_scaled)
    assert np.allclose(t6[[0, 2, 4]], t3, atol=1e-6) and np.allclose(t6[[1, 3, 5]], 0, atol=1e-6)


def test_the_symmetry_is_checked_not_assumed(dh_posed):
    assert pull_plane_symmetry(dh_posed, 0.0).symmetric
    assert not pull_plane_symmetry(dh_posed, math.radians(30)).symmetric
    auto = PosedAnchorSolver(get_medium('m90_sand'))
    assert auto.solve(dh_posed, 0.0).space == 'sagittal'
    assert auto.solve(dh_posed, 0.0, math.radians(30)).space == '6d'


def test_a_yawed_pull_slips_out_of_the_plane(dh_posed):
    r = PosedAnchorSolver(get_medium('m90_sand')).solve(dh_posed, 0.0, math.radians(30))
    assert r.status is Status.OK and r.space == '6d'
    t = np.array(r.slip_twist_scaled)
    # vy, wx, wz: the body slides sideways and turns about z and x.
    assert np.linalg.norm(t[[1, 3, 5]]) > 0.3
    mirrored = PosedAnchorSolver(get_medium('m90_sand')).solve(dh_posed, 0.0, math.radians(-30))
    assert mirrored.capacity_N == pytest.approx(r.capacity_N, rel=1e-6)   # mirror image
    tm = np.array(mirrored.slip_twist_scaled)
    assert np.allclose(tm, t * np.array([1, -1, 1, -1, 1, -1]), atol=1e-5)


def test_plot_shows_capacity_against_yaw(tmp_path, capsys):
    import json

    from rftgls_core.cli.main import main
    png = tmp_path / 'yaw.png'
    code = main(['plot', '--robot', 'minirquad', '--h', '0.034', '--theta-b', '5',
                 '--theta-l1', '-40', '--theta-l2', '30', '--phi', '0', '--against-yaw',
                 '--out', str(png)])
    assert code == 0, capsys.readouterr().err
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    data = json.loads(png.with_suffix('.json').read_text())['by_yaw']
    spaces = dict(zip(np.round(np.degrees(data['yaw_rad'])), data['space']))
    assert spaces[0.0] == 'sagittal' and spaces[30.0] == '6d'


def test_a_ray_through_a_jump_exits_on_the_closure(dh_posed):
    # Yaw 70 deg: no twist maps onto the ray (Newton stalls at a jump); the patch search finds
    # the exit of the bridged closure. Reference: continuity in yaw, the neighbours 65 and 75 deg
    # are smooth Newton roots.
    solver = PosedAnchorSolver(get_medium('m90_sand'))
    caps = {y: solver.solve(dh_posed, 0.0, math.radians(y)) for y in (65.0, 70.0, 75.0)}
    assert caps[70.0].status is Status.OK and 'on_jump' in caps[70.0].flags
    assert 'patch search' in caps[70.0].detail
    assert caps[75.0].capacity_N < caps[70.0].capacity_N < caps[65.0].capacity_N
