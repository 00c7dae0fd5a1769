"""Bring up MiniRQuad's stack on a robot: serial bridge, capacity_node, state_publisher (TF),
behavior_node.

    ros2 launch rftgls_ros bringup.launch.py port:=/dev/ttyACM0 sled_mass_kg:=0.4

Parameters come from the installed YAML files (share/rftgls_ros/params); capacity_node reads the
tether angle behavior_node estimates (/winch/phi), as `make demo` does. Needs a ROS 2 Jazzy
install with launch_ros; on the pip-wheel machines `make demo` starts the same stack, and
tests/ros/test_launch_files.py checks this file without running it.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    params = os.path.join(get_package_share_directory('rftgls_ros'), 'params')
    port = LaunchConfiguration('port')
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='/dev/ttyACM0',
                              description='serial port of the MiniRQuad MCU'),
        DeclareLaunchArgument('sled_mass_kg', default_value='0.4',
                              description='mass of the sled to haul, kg'),
        DeclareLaunchArgument('cycles', default_value='3',
                              description='walk-burrow-tug cycles'),
        Node(package='minirquad_driver', executable='bridge_node', name='bridge_node',
             parameters=[{'port': port}], output='screen'),
        Node(package='rftgls_ros', executable='capacity_node', name='capacity_node',
             parameters=[os.path.join(params, 'capacity_node.yaml'),
                         {'phi_topic': '/winch/phi'}],
             output='screen'),
        # /tf_static and /tf from the URDF, the joint states, the IMU pitch and the height.
        Node(package='rftgls_ros', executable='state_publisher', name='state_publisher',
             parameters=[{'robot': 'minirquad'}], output='screen'),
        Node(package='rftgls_ros', executable='behavior_node', name='behavior_node',
             parameters=[os.path.join(params, 'behavior_node.yaml'),
                         {'sled_mass_kg': LaunchConfiguration('sled_mass_kg'),
                          'cycles': LaunchConfiguration('cycles')}],
             output='screen'),
    ])
