"""ROS-free parts of capacity_node: its predictor from its parameters, the estimator, and
message-free conversions.

Nothing in this sub-package imports rclpy, so tests (and other tools) can drive it directly.
"""
from rftgls_node_base.parameters import ConfigError

from .estimator import INPUTS, CapacityEstimator, Estimate, EstimatorConfig
from .node_predictor import DEFAULT_MAP, node_predictor

__all__ = ['CapacityEstimator', 'ConfigError', 'DEFAULT_MAP', 'Estimate', 'EstimatorConfig',
           'INPUTS', 'node_predictor']
