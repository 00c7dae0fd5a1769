"""Robot models posed from anchor states: the sign conventions of
docs/design/architecture.md#frames-and-signs."""
import math

import numpy as np
import pytest

from rftgls_core.robots.presets import get_robot, minirquad, prototype
from rftgls_core.types import AnchorState, Pull


def leg_facets(posed, axle, side):
    """Facets of one leg (axle 0 proximal, 1 distal; side +1 left, -1 right)."""
    n = len(posed.robot.leg_mesh.faces)
    start = (0 if side > 0 else 2 * n) + axle * n
    return posed.facets.centroids[start:start + n]


def test_leg_angle_zero_points_the_chord_down():
    robot = prototype()
    posed = robot.pose(AnchorState(0.02, 0.0, 0.0, 0.0), Pull.BACKWARD)
    for axle in (0, 1):
        c = leg_facets(posed, axle, +1)
        hip_z = 0.02 + robot.axle_z
        # toe at 90 mm below the hip (arc diameter), half a thickness of slack
        assert c[:, 2].min() == pytest.approx(hip_z - 0.090, abs=0.004)
        assert c[:, 1].mean() == pytest.approx(robot.leg_y[axle], abs=1e-9)


def test_larger_theta_l1_puts_proximal_contact_further_from_p():
    robot = minirquad()
    xs = []
    for deg in (-40, 0, 40):
        posed = robot.pose(AnchorState.from_degrees(0.02, 0, deg, 0))
        c = leg_facets(posed, 0, +1)
        xs.append(c[np.argmin(c[:, 2]), 0])  # lowest point of the proximal leg
    assert xs[0] < xs[1] < xs[2]


def test_positive_pitch_raises_the_axle_end():
    robot = prototype()
    flat = robot.pose(AnchorState(0.02, 0.0, 0.0, 0.0))
    up = robot.pose(AnchorState(0.02, math.radians(10), 0.0, 0.0))
    assert leg_facets(up, 1, +1)[:, 2].mean() > leg_facets(flat, 1, +1)[:, 2].mean()


def test_gravity_wrench_about_p():
    robot = minirquad()
    posed = robot.pose(AnchorState.from_degrees(0.03, 0, 0, 0))
    mg = robot.mass * 9.81
    assert np.allclose(posed.gravity_wrench, (0.0, -mg, mg * robot.com[0]))
    tilted = robot.pose(AnchorState.from_degrees(0.03, 20, 0, 0))
    x_com = robot.com[0] * math.cos(math.radians(20)) - robot.com[1] * math.sin(math.radians(20))
    assert tilted.gravity_wrench[2] == pytest.approx(mg * x_com)


def test_right_legs_mirror_left_legs_and_pull_flips_the_c():
    posed = minirquad().pose(AnchorState.from_degrees(0.02, 3, -10, 25), Pull.FORWARD)
    half = len(posed.facets) // 2
    c, n = posed.facets.centroids, posed.facets.normals
    assert np.allclose(c[half:], c[:half] * [1, -1, 1])
    assert np.allclose(n[half:], n[:half] * [1, -1, 1])
    back = minirquad().pose(AnchorState.from_degrees(0.02, 0, 0, 0), Pull.BACKWARD)
    fwd = minirquad().pose(AnchorState.from_degrees(0.02, 0, 0, 0), Pull.FORWARD)
    hip_x = minirquad().axle_x[0]
    # the C bulges away from p (+x_B) for forward pulls and toward p for backward pulls
    assert leg_facets(fwd, 0, +1)[:, 0].mean() > hip_x > leg_facets(back, 0, +1)[:, 0].mean()


def test_unknown_robot_is_a_clear_error():
    with pytest.raises(ValueError, match='known robots'):
        get_robot('rhex')
