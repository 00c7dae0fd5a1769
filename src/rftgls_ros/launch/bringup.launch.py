"""Bring up MiniRQuad's stack on a robot: serial bridge, capacity_node, state_publisher
(/robot_description and TF), behavior_node.

    ros2 launch rftgls_ros bringup.launch.py port:=/dev/ttyACM0 sled_mass_kg:=0.4
    ros2 launch rftgls_ros bringup.launch.py port:=/dev/ttyACM0 autostart:=false   # goals:
    ros2 action send_goal /behavior_node/walk_burrow_tug rftgls_interfaces/action/WalkBurrowTug \
        "{sled_mass_kg: 0.4, cycles: 3}"

Parameters come from the installed YAML files (share/rftgls_ros/params); capacity_node reads the
tether angle behavior_node estimates (/winch/phi), as `make demo` does. The robot model is the
URDF of minirquad_description (share/minirquad_description/urdf). Launch arguments are
converted to their parameters' declared types (ParameterValue), so `sled_mass_kg:=1` is the
float 1.0, not the integer YAML would make of it. Needs a ROS 2 Jazzy install with launch_ros;
on the pip-wheel machines `python -m rftgls_ros.launch_run` starts the same command lines
(tests/ros/test_launch_run.py).

The tug path (bridge_node, capacity_node, behavior_node: the nodes a winch stop goes through)
runs behind `tug_path_prefix`, by default `nice -n -5`: above a normal-priority load, as the
stop promise was measured (docs/design/tug-safety.md, "Priority of the tug path"). Without the
right to raise a priority (CAP_SYS_NICE, or an RLIMIT_NICE in /etc/security/limits.conf) nice
prints "cannot set niceness" and runs the node at its normal priority; `tug_path_prefix:=''`
switches it off. `ros2 launch --launch-prefix` (gdb, valgrind) still applies to these nodes,
after the nice; `--launch-prefix-filter` does not (a prefix set in a launch file replaces it).
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
                        'minirquad.urdf')
    with open(urdf) as f:
        robot_description = f.read()
    port = ParameterValue(LaunchConfiguration('port'), value_type=str)
    # launch joins the substitutions and shlex-splits the result in front of the command.
    tug_path = [LaunchConfiguration('tug_path_prefix'), ' ',
                LaunchConfiguration('launch-prefix', default='')]
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='/dev/ttyACM0',
                              description='serial port of the MiniRQuad MCU'),
        DeclareLaunchArgument('sled_mass_kg', default_value='0.4',
                              description='mass of the sled to haul, kg'),
        DeclareLaunchArgument('cycles', default_value='3',
                              description='walk-burrow-tug cycles'),
        DeclareLaunchArgument('autostart', default_value='true',
                              description='behavior_node runs sled_mass_kg/cycles at start; '
                                          'false: it waits for walk_burrow_tug goals'),
        DeclareLaunchArgument('tug_path_prefix', default_value='nice -n -5',
                              description='command in front of bridge_node, capacity_node and '
                                          "behavior_node ('' = none)"),
        Node(package='minirquad_driver', executable='bridge_node', name='bridge_node',
             parameters=[{'port': port}], prefix=tug_path, output='screen'),
        Node(package='rftgls_ros', executable='capacity_node', name='capacity_node',
             parameters=[os.path.join(params, 'capacity_node.yaml'),
                         {'phi_topic': '/winch/phi'}],
             prefix=tug_path, output='screen'),
        # /robot_description, /tf_static and /tf from the URDF, the joint states, the IMU
        # pitch and the height (robot_state_publisher's topics, plus the body pose).
        Node(package='rftgls_ros', executable='state_publisher', name='state_publisher',
             parameters=[{'robot_description': robot_description}], output='screen'),
        Node(package='rftgls_ros', executable='behavior_node', name='behavior_node',
             parameters=[os.path.join(params, 'behavior_node.yaml'),
                         {'sled_mass_kg': ParameterValue(LaunchConfiguration('sled_mass_kg'),
                                                         value_type=float),
                          'cycles': ParameterValue(LaunchConfiguration('cycles'),
                                                   value_type=int),
                          'autostart': ParameterValue(LaunchConfiguration('autostart'),
                                                      value_type=bool)}],
             remappings=[('imu', 'imu/data')],   # REP-145's topic (the bridge has both)
             prefix=tug_path, output='screen'),
    ])
