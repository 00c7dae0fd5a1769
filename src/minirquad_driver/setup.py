"""ament_python package minirquad_driver; also installs with plain pip."""
from setuptools import find_packages, setup

PACKAGE = 'minirquad_driver'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    package_data={PACKAGE: []},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    extras_require={'test': ['pytest']},
    install_requires=['setuptools', 'pyserial'],
    zip_safe=False,
    description='MiniRQuad serial protocol (COBS + CRC-16 frames) and the serial bridge node.',
    license='BSD-3-Clause',
    entry_points={
        'console_scripts': [
            'bridge_node = minirquad_driver.bridge_node:main',
        ],
    },
)
