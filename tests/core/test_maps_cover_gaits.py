"""The shipped MiniRQuad capacity map covers every leg pose the burrow planner can end in, and
every body pitch its simulations predict, by capacity_node's pitch band.

A tug is checked against the capacity map at the burrowed pose. A planned gait whose final
leg pose sits on the map's edge is checked against nothing: legs that stop one servo count
past the commanded angle (a real XL330 reads 0.088 deg per count; the simulated physics body
stopped the distal legs at -20.09 deg for a -20 deg command) are off the grid, and
capacity_node answers out_of_range for the whole anchor, so no tug ever starts
(docs/design/walk-burrow-physics.md, "The simulator"). The map's leg axes must therefore
reach at least one leg step beyond every final pose the planner commands and every leg pose
its simulations predict.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from rftgls_core.maps import CapacityMap, shipped_map_path
from rftgls_core.maps.grid import default_grid
from rftgls_core.planning.gait_map import load, shipped_paths
from rftgls_core.planning.gaits import SHIPPED_GRID, with_modes

# One leg step of the map's theta_L2 axis (maps/grid.py, minirquad_grid). Far more than any
# servo's hold error (counts of 0.088 deg) and a stalled leg's shortfall is toward the
# retracting pose, which the check below covers through the predicted poses.
MARGIN_RAD = math.radians(10.0)
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def leg_axes():
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    axes = cmap.grid.axes
    # the shipped file is the default grid (a rebuild with the documented command gives it)
    for mine, shipped in zip(default_grid('minirquad').axes, axes):
        np.testing.assert_array_equal(mine, shipped)
    return axes[2], axes[3]


def _inside(value: float, axis: np.ndarray, margin: float) -> bool:
    return bool(axis[0] + margin - 1e-12 <= value <= axis[-1] - margin + 1e-12)


def test_every_commanded_final_pose_is_a_leg_step_inside(leg_axes):
    l1, l2 = leg_axes
    gaits = with_modes(SHIPPED_GRID.gaits())
    for p in shipped_paths('minirquad'):
        gaits += load(p).gaits()
    outside = [g.to_json() for g in gaits
               if not (_inside(g.final[0], l1, MARGIN_RAD) and _inside(g.final[1], l2, MARGIN_RAD))]
    assert not outside, outside


def test_every_predicted_leg_pose_is_on_the_map(leg_axes):
    l1, l2 = leg_axes
    for p in shipped_paths('minirquad'):
        pose = load(p).arrays['pose']
        legs = pose[np.isfinite(pose[..., 2])][:, 2:4]
        assert len(legs) > 0, p.name
        off = [np.degrees(q).round(2).tolist() for q in legs
               if not (_inside(q[0], l1, 0.0) and _inside(q[1], l2, 0.0))]
        assert not off, (p.name, off)


def _node_pitch_sigma() -> float:
    """capacity_node's one-sigma pitch band (rad): its lower bound takes the pitch that far
    each side of the estimate, and a state off the map counts as 0 N."""
    params = yaml.safe_load((REPO / 'ros2_ws/params/capacity_node.yaml').read_text())
    return float(params['/**/capacity_node']['ros__parameters']['theta_b_sigma_rad'])


def _top_predicted_pitch() -> float:
    """The highest body pitch (rad) any shipped gait map predicts, over every gait and run."""
    tops = []
    for p in shipped_paths('minirquad'):
        pitch = load(p).arrays['pose'][..., 1]
        tops.append(float(np.nanmax(pitch)))
    return max(tops)


def test_the_pitch_axis_reaches_past_every_predicted_pitch_by_the_nodes_band():
    # A planned gait predicted at 15.0 deg was confirmed on a map whose pitch axis ended at
    # 15 deg; capacity_node's bound, taking the pitch 1 deg each side, found 0 N there and the
    # tug was refused (docs/design/burrow-planner.md). Nose-down runs (negative pitches, the
    # body tipped onto its legs at h 60-130 mm) are off the height axis as well: out_of_range
    # is the honest answer for a burrow that went that wrong.
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    top, sigma = _top_predicted_pitch(), _node_pitch_sigma()
    assert 0.0 < sigma < math.radians(5.0)
    assert top + sigma <= cmap.grid.axes[1][-1], (math.degrees(top), math.degrees(sigma))
    assert top + sigma > math.radians(15.0)      # the old axis (-5:5:15 deg) fell short


def test_the_check_fails_on_the_old_edge():
    """The margin rule rejects the grid this test was written against (theta_L2 from -20)."""
    old = np.radians(-20.0 + 10.0 * np.arange(7))
    assert not _inside(math.radians(-20.0), old, MARGIN_RAD)
    assert not _inside(math.radians(-20.09), old, 0.0)
