"""ament_python package rftgls_node_base; also installs with plain pip."""
from setuptools import find_packages, setup

PACKAGE = 'rftgls_node_base'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    extras_require={'test': ['pytest']},
    install_requires=['setuptools'],
    zip_safe=False,
    description=('What every rclpy node of the RFT-GLS stack shares: start-up, parameters, '
                 'DDS on loopback, diagnostics status.'),
    license='BSD-3-Clause',
)
