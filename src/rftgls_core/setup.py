"""ament_python package rftgls_core; also installs with plain pip."""
import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'rftgls_core'
# Repository root, through the real path of this file: colcon runs it from ros2_ws/src (a
# symlink to src/) or from a copy in build/<pkg>, so '../..' would name another folder.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))


def _outside(*pattern: str) -> list[str]:
    """Files of the repository outside this package, relative to where setup.py runs
    (data_files must be relative)."""
    return sorted(os.path.relpath(f, os.getcwd()) for f in glob(os.path.join(ROOT, *pattern)))

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    package_data={PACKAGE: ['data/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        # The shipped maps (repository maps/): a plain `colcon build` installs
        # them to share/rftgls_core/maps, where maps.shipped.maps_dir() finds them.
        ('share/' + PACKAGE + '/maps', _outside('maps', '*.h5')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    description=('RFT-GLS core: granular RFT, limit surfaces, load capacity, slip twist, HDF5 '
                 'maps. No ROS inside.'),
    license='BSD-3-Clause',
    entry_points={
        'console_scripts': [
            'rftgls = rftgls_core.cli.main:main',
        ],
    },
)
