"""ament_python package minirquad_sim; also installs with plain pip."""
from setuptools import find_packages, setup

PACKAGE = 'minirquad_sim'

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
    description=('The simulated MiniRQuad: plant physics (legs, servos, sand, winch and sled, '
                 'INA219), the reference microcontroller speaking the real protocol on a pty, '
                 'fault injection.'),
    license='BSD-3-Clause',
    entry_points={
        'console_scripts': [
            'minirquad_sim = minirquad_sim.main:main',
        ],
    },
)
