"""Fixtures of the capacity_node tests (the repository conftest gives ros_context and spawn)."""
from __future__ import annotations

import pytest


@pytest.fixture(scope='session')
def live_predictor():
    """One live twist-mesh predictor per worker (the twist sphere is built once)."""
    from rftgls_ros.capacity.node_predictor import node_predictor
    return node_predictor('', 'twist-mesh')


@pytest.fixture(scope='session')
def small_map(tmp_path_factory):
    """A real (tiny) MiniRQuad map built with rftgls_core.maps around the DH anchor.

    h = 30, 40, 200 mm (the 200 mm nodes have no buried leg -> unsupported cells above 40 mm),
    theta_b 0..10 deg, theta_l1 -40..-20 deg, theta_l2 20..30 deg, phi -20 and 0 deg,
    backward pull only. Queries: DH -> ok, theta_b 15 deg -> off the grid (out_of_range),
    h 0.1 -> unsupported.
    """
    from rftgls_core.maps import MapGrid, build_map, save_map
    grid = MapGrid.from_degrees([30.0, 40.0, 200.0], [0.0, 10.0], [-40.0, -20.0],
                                [20.0, 30.0], [-20.0, 0.0], pulls=('backward',))
    data = build_map('minirquad', 'm90_sand', grid, method='twist-mesh', workers=1)
    return save_map(tmp_path_factory.mktemp('maps') / 'small_minirquad.h5', data)
