"""ament_python package minirquad_description: data only (URDF and meshes under share/)."""
from glob import glob

from setuptools import setup

PACKAGE = 'minirquad_description'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=[],
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/urdf', sorted(glob('urdf/*.urdf'))),
        ('share/' + PACKAGE + '/meshes', sorted(glob('meshes/*.stl'))),
    ],
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    description='URDF and meshes of MiniRQuad and the lab prototype.',
    license='BSD-3-Clause',
)
