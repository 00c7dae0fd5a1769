"""Terminal teleop of the winch with the live RFT-GLS prediction (``ros2 run rftgls_ros teleop``).

``model.TeleopModel`` holds the keys, the guard and the screen text without ROS;
``main`` is the rclpy node and the raw-mode terminal loop.
"""
from .model import KEYS, TeleopConfig, TeleopModel

__all__ = ['KEYS', 'TeleopModel', 'TeleopConfig']
