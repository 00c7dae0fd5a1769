"""ament_python package rftgls_core; also installs with plain pip."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'rftgls_core'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    package_data={PACKAGE: ['data/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        # The shipped maps (shipped_maps is a symlink to the repository's maps/): a plain
        # `colcon build` installs them to share/rftgls_core/maps, where
        # maps.shipped.maps_dir() finds them.
        ('share/' + PACKAGE + '/maps', sorted(glob('shipped_maps/*.h5'))),
    ],
    # dask: optional, only for distributed map builds (`rftgls map build --scheduler`).
    extras_require={'test': ['pytest'], 'distributed': ['dask[distributed]']},
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
