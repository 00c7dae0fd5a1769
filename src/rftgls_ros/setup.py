"""ament_python package rftgls_ros; also installs with plain pip."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'rftgls_ros'
# Installed to share/rftgls_ros (found through the ament index by launch files and tools):
# launch files, the node parameter files (params is a symlink to the repository's
# ros2_ws/params) and the RViz / Foxglove layouts.
SHARE = 'share/' + PACKAGE

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    package_data={PACKAGE: ['lab/samples/*', 'lab/samples/*/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        (SHARE + '/launch', sorted(glob('launch/*.launch.py'))),
        (SHARE + '/params', sorted(glob('params/*.yaml'))),
        (SHARE + '/config', sorted(glob('config/*.rviz') + glob('config/*.json'))),
    ],
    extras_require={'test': ['pytest']},
    install_requires=['setuptools'],
    zip_safe=False,
    description=('ROS 2 nodes of the RFT-GLS anchoring stack: capacity_node, behavior_node, '
                 'teleop, bag replay.'),
    license='BSD-3-Clause',
    entry_points={
        'rftgls.commands': [
            'calibrate = rftgls_ros.lab.calibrate:add_parser',
        ],
        'console_scripts': [
            'rftgls_lab_track = rftgls_ros.lab.aruco_tracking:main',
            'rftgls_lab_tracking_accuracy = rftgls_ros.lab.tracking_accuracy:main',
            'rftgls_lab_synthetic = rftgls_ros.lab.synthetic:main',
            'rftgls_lab_eval = rftgls_ros.lab.evaluate:main',
            'rftgls_lab_calibrate = rftgls_ros.lab.calibrate:main',
            'rftgls_lab_replay = rftgls_ros.lab.replay:main',
            'capacity_node = rftgls_ros.capacity_node:main',
            'capacity_bench = rftgls_ros.capacity_bench:main',
            'behavior_node = rftgls_ros.behavior_node:main',
            'behavior_demo = rftgls_ros.demo:main',
            'teleop = rftgls_ros.teleop.main:main',
            'state_publisher = rftgls_ros.state_publisher:main',
        ],
    },
)
