"""Replay a lab pull-test bag into capacity_node (the lab prototype in glass beads).

    ros2 launch rftgls_ros replay.launch.py bag:=/path/to/backward_L1-020_L2+020 rate:=1.0

capacity_node is configured as in src/rftgls_ros/lab_README.md: the prototype's map, pitch and
tether angle from the tracked topics, and inputs aged by receipt time (recorded stamps are in
the past). `pull` must match the bag's pull direction (its metadata says which).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    params = os.path.join(get_package_share_directory('rftgls_ros'), 'params')
    urdf = os.path.join(get_package_share_directory('minirquad_description'), 'urdf',
                        'prototype.urdf')
    with open(urdf) as f:
        robot_description = f.read()
    return LaunchDescription([
        DeclareLaunchArgument('bag', description='lab bag directory (metadata.yaml + .mcap)'),
        DeclareLaunchArgument('rate', default_value='1.0',
                              description='replay speed factor (0 = as fast as possible)'),
        DeclareLaunchArgument('pull', default_value='backward',
                              description='pull direction of the bag (forward | backward)'),
        # The replay publishes /robot_description only for --anchor (state_publisher has the
        # prototype's URDF here).
        Node(package='rftgls_ros', executable='rftgls_lab_replay',
             arguments=[LaunchConfiguration('bag'), '--rate', LaunchConfiguration('rate'),
                        '--no-description'],
             output='screen'),
        Node(package='rftgls_ros', executable='capacity_node', name='capacity_node',
             parameters=[os.path.join(params, 'capacity_node.yaml'),
                         {'robot': 'prototype', 'medium': 'glass_beads',
                          'map_file': 'maps/prototype_glass_beads.h5',
                          'pull': ParameterValue(LaunchConfiguration('pull'), value_type=str),
                          'pitch_topic': '/lab/theta_b', 'phi_topic': '/winch/phi',
                          'tension_component': 'tether',
                          'tension_frame_id': 'lab_world',   # the bag's force is a world vector
                          'freshness_source': 'receipt_time',
                          # every recorded sample gets its answer, in order
                          'trigger_max_queue_s': 0.0}],
             output='screen'),
        # TF for the replay: the bag's /tf_static holds lab_world -> aruco_tank (-> camera);
        # state_publisher hangs the robot on lab_world (odom_frame): base_link, legs,
        # winch_link and `anchor` (capacity_node's frame). Its x, y of p are not taken from the
        # tracker (state_publisher assumes 0), pitch and height are the replayed ones.
        Node(package='rftgls_ros', executable='state_publisher', name='state_publisher',
             parameters=[{'robot_description': robot_description, 'odom_frame': 'lab_world',
                          'pitch_topic': '/lab/theta_b'}],
             output='screen'),
    ])
