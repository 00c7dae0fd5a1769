"""The simulated MiniRQuad (a pty that speaks the MCU protocol) with the whole stack on it.

    ros2 launch rftgls_ros sim.launch.py sled_mass_kg:=0.6

minirquad_sim keeps a symlink `port` pointing at its pty; bringup.launch.py's bridge opens it
(and retries until it exists). The simulator is not a ROS node: it is started with launch's
ExecuteProcess (no ROS arguments). `make demo` runs the same stack without launch.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.substitutions import ExecutableInPackage


def generate_launch_description():
    launch_dir = os.path.join(get_package_share_directory('rftgls_ros'), 'launch')
    port = LaunchConfiguration('port')
    sled = LaunchConfiguration('sled_mass_kg')
    return LaunchDescription([
        DeclareLaunchArgument('port', default_value='/tmp/minirquad_sim_tty',
                              description='symlink the simulator keeps at its pty'),
        DeclareLaunchArgument('sled_mass_kg', default_value='0.4',
                              description='simulated sled mass, kg'),
        DeclareLaunchArgument('tug_path_prefix', default_value='nice -n -5',
                              description="bringup.launch.py's: in front of the tug path's "
                                          "nodes ('' = none)"),
        ExecuteProcess(cmd=[ExecutableInPackage(executable='minirquad_sim',
                                                package='minirquad_sim'),
                            '--symlink', port, '--sled-mass', sled], output='screen'),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(launch_dir, 'bringup.launch.py')),
            launch_arguments={'port': port, 'sled_mass_kg': sled,
                              'tug_path_prefix': LaunchConfiguration('tug_path_prefix')}.items()),
    ])
