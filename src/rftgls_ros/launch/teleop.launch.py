"""The simulated MiniRQuad with what the teleoperated tug needs: simulator, serial bridge,
capacity_node and state_publisher (no behavior_node: teleop commands the winch instead).

    ros2 launch rftgls_ros teleop.launch.py sled_mass_kg:=0.4      # then, in a terminal:
    ros2 run rftgls_ros teleop

On the pip-wheel machines `make teleop-sim` runs this file with rftgls_ros.launch_run.
capacity_node reads the tether angle teleop publishes (/winch/phi, from the rope paid out and
the attachment height, rftgls_ros.tether.TetherTracker, shared with behavior_node) and the
burrowed height teleop sends as modelled by the burrow simulation with its band, so its
estimate of a burrowed anchor is `ok` with provenance `height:modelled`.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import ExecutableInPackage


def generate_launch_description():
    params = os.path.join(get_package_share_directory('rftgls_ros'), 'params')
    urdf = os.path.join(get_package_share_directory('minirquad_description'), 'urdf',
                        'minirquad.urdf')
    with open(urdf) as f:
        robot_description = f.read()
    port = LaunchConfiguration('port')
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='/tmp/minirquad_sim_tty',
                              description='symlink the simulator keeps at its pty'),
        DeclareLaunchArgument('sled_mass_kg', default_value='0.4',
                              description='simulated sled mass, kg'),
        ExecuteProcess(cmd=[ExecutableInPackage(executable='minirquad_sim',
                                                package='minirquad_sim'),
                            '--symlink', port, '--sled-mass',
                            LaunchConfiguration('sled_mass_kg')], output='screen'),
        Node(package='minirquad_driver', executable='bridge_node', name='bridge_node',
             parameters=[{'port': ParameterValue(port, value_type=str)}], output='screen'),
        Node(package='rftgls_ros', executable='capacity_node', name='capacity_node',
             parameters=[os.path.join(params, 'capacity_node.yaml'),
                         {'phi_topic': '/winch/phi'}],
             output='screen'),
        Node(package='rftgls_ros', executable='state_publisher', name='state_publisher',
             parameters=[{'robot_description': robot_description}], output='screen'),
    ])
