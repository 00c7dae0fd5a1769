"""What every rclpy executable of the stack shares: start-up and shutdown (`node_main`),
parameters with descriptors and the configuration error (`parameters`), DDS kept on loopback
(`dds_loopback`) and the diagnostics status record (`diagnostics`). The bottom ROS package:
it depends on rclpy and the shared conventions only, so the driver that runs on the robot can
use it without pulling in the solver."""
