"""rftgls_conventions: every shared convention checked against an independent source
(scipy's Rotation for quaternions, hand-worked angles for the circle means)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import rftgls_conventions as cv
from rftgls_core.types import pull_direction

DEG = math.pi / 180.0


@pytest.mark.parametrize('theta_b', [-80 * DEG, -20 * DEG, 0.0, 5 * DEG, 60 * DEG])
def test_pitch_quaternion_round_trip_and_sign(theta_b):
    q = cv.pitch_to_quat_xyzw(theta_b)
    # scipy: rotation about +y by -theta_b (REP-103 pitch = -theta_b), quaternion (x, y, z, w).
    ref = Rotation.from_euler('y', -theta_b).as_quat()
    np.testing.assert_allclose(q, ref, atol=1e-12)
    assert cv.quat_xyzw_to_pitch(*q) == pytest.approx(theta_b, abs=1e-12)
    # Nose up: the body x axis has a positive world z component when theta_b > 0.
    x_world = Rotation.from_quat(q).apply([1.0, 0.0, 0.0])
    assert math.asin(x_world[2]) == pytest.approx(theta_b, abs=1e-12)


def test_pitch_ignores_yaw_and_roll_and_normalises():
    r = Rotation.from_euler('ZYX', [40 * DEG, -15 * DEG, 25 * DEG])  # intrinsic yaw, pitch, roll
    assert cv.quat_xyzw_to_pitch(*r.as_quat()) == pytest.approx(15 * DEG)
    assert cv.quat_xyzw_to_pitch(0.0, 0.0, 0.0, 3.0) == 0.0
    with pytest.raises(ValueError):
        cv.quat_xyzw_to_pitch(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError):
        cv.quat_xyzw_to_pitch(math.nan, 0.0, 0.0, 1.0)


def test_body_and_world_axes_match_scipy():
    r = Rotation.from_euler('xyz', [10 * DEG, -25 * DEG, 70 * DEG])
    q = r.as_quat()
    np.testing.assert_allclose(cv.body_z_in_world(*q), r.apply([0, 0, 1]), atol=1e-12)
    np.testing.assert_allclose(cv.world_z_in_body(*q), r.inv().apply([0, 0, 1]), atol=1e-12)


def test_axle_mean_on_the_circle_and_agreement():
    mean, spread = cv.axle_angle(-179 * DEG, 179 * DEG)
    assert abs(abs(mean) - math.pi) < 1e-9 and spread == pytest.approx(2 * DEG)
    legs = {'proximal_left': -40 * DEG, 'proximal_right': -38 * DEG,
            'distal_left': 30 * DEG, 'distal_right': 40 * DEG}
    a = cv.axle_angles(legs, 5 * DEG)
    assert a.theta_l1 == pytest.approx(-39 * DEG) and a.theta_l2 == pytest.approx(35 * DEG)
    assert a.spread_rad == pytest.approx((2 * DEG, 10 * DEG))
    assert a.disagreeing == ('distal',) and not a.agree
    assert cv.axle_angles(legs, 20 * DEG).agree
    with pytest.raises(KeyError):
        cv.axle_angles({'proximal_left': 0.0}, 1.0)


def test_wrap_angle_range():
    assert cv.wrap_angle(math.pi) == pytest.approx(-math.pi)
    assert cv.wrap_angle(-0.3) == -0.3
    assert cv.wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_joint_names_and_keys():
    assert cv.JOINT_NAMES == ('leg_proximal_left', 'leg_proximal_right', 'leg_distal_left',
                              'leg_distal_right', 'winch_rope')
    assert cv.leg_keys_from_joint_names(['winch_rope', 'leg_distal_left', 'x']) == \
        {'leg_distal_left': 'distal_left'}


def test_tether_direction_and_angle():
    for phi in (-20 * DEG, 0.0, 30 * DEG):
        assert cv.tether_direction_xz(phi) == pytest.approx(pull_direction(phi)[:2])
    # p 0.2 sin(20 deg) above the attachment, 0.2 m of tether: phi = -20 deg.
    h = 0.01 + 0.2 * math.sin(20 * DEG)
    assert cv.tether_phi(h, 0.01, 0.2) == pytest.approx(-20 * DEG)
    assert cv.tether_phi(1.0, 0.0, 0.0) == pytest.approx(-math.pi / 2)   # clamped


def test_edge_units():
    assert cv.deg_to_rad(180.0) == pytest.approx(math.pi)
    assert cv.mm_to_m(12.5) == pytest.approx(0.0125)


def test_vectorised_pitch_quaternion_matches_the_scalar_form_on_the_whole_circle():
    th = np.linspace(-3.1, 3.1, 41)
    q = cv.pitch_to_quat_xyzw_array(th)
    assert q.shape == (41, 4)
    np.testing.assert_allclose(q, [cv.pitch_to_quat_xyzw(t) for t in th], atol=1e-15)
    np.testing.assert_allclose(cv.pure_pitch_quat_xyzw_to_pitch_array(q), th, atol=1e-12)
    # -q is the same rotation; the result stays in (-pi, pi]
    back = cv.pure_pitch_quat_xyzw_to_pitch_array(-q)
    np.testing.assert_allclose(back, th, atol=1e-12)
    small = th[np.abs(th) < math.pi / 2]
    np.testing.assert_allclose([cv.quat_xyzw_to_pitch(*r) for r in q[np.abs(th) < math.pi / 2]],
                               small, atol=1e-12)


@pytest.mark.parametrize('phi', [0.0, -0.35, 0.35, -1.5, 2.5])
def test_tether_phi_from_xz_inverts_the_direction(phi):
    x, z = cv.tether_direction_xz(phi)
    assert cv.tether_phi_from_xz(3.0 * x, 3.0 * z) == pytest.approx(phi, abs=1e-12)
