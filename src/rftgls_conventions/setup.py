"""ament_python package rftgls_conventions; also installs with plain pip."""
from setuptools import find_packages, setup

PACKAGE = 'rftgls_conventions'

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
    description=('The conventions every RFT-GLS package shares: joint names, leg angles, body '
                 'pitch, tether direction, units. Pure Python.'),
    license='BSD-3-Clause',
)
