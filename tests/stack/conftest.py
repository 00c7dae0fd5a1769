"""Fixtures of the behaviour tests without ROS (the repository conftest gives the ROS ones)."""
from __future__ import annotations

import pytest


@pytest.fixture(scope='module')
def predictor():
    """The stack's predictor on the shipped map, as behavior_node's local_map source builds it
    (a module that needs capacity_node's live edge answers defines its own)."""
    from rftgls_ros.capacity.node_predictor import DEFAULT_MAP, node_predictor
    return node_predictor(DEFAULT_MAP, robot=None, medium=None)
