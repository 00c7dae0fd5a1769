"""ROS-free parts of capacity_node: predictors, the estimator, and message-free conversions.

Nothing in this sub-package imports rclpy, so tests (and other tools) can drive it directly.
"""
from .estimator import INPUTS, CapacityEstimator, Estimate, EstimatorConfig
from .predictor import ConfigError, LivePredictor, MapPredictor, Predictor, predictor_from_params

__all__ = ['CapacityEstimator', 'ConfigError', 'Estimate', 'EstimatorConfig', 'INPUTS',
           'LivePredictor', 'MapPredictor', 'Predictor',
           'predictor_from_params']
