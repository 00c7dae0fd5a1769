"""ament_python package rftgls_ros; also installs with plain pip."""
from setuptools import find_packages, setup

PACKAGE = 'rftgls_ros'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    package_data={PACKAGE: []},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    description='ROS 2 nodes of the RFT-GLS anchoring stack: capacity_node, behavior_node, teleop, bag replay.',
    license='BSD-3-Clause',
    entry_points={
        'console_scripts': [
            'capacity_node = rftgls_ros.capacity_node:main',
            'capacity_bench = rftgls_ros.capacity_bench:main',
        ],
    },
)
