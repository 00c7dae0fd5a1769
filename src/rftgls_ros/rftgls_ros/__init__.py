"""ROS 2 nodes of the RFT-GLS anchoring stack (rclpy). The maths lives in rftgls_core."""
