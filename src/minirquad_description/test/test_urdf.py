"""The description package's URDFs are the ones rftgls_core writes (one source: the robot
presets), with the mesh as a package:// URI; their joints are the driver's /joint_states
names, continuous; every link with a mesh has a physically valid inertia; ROS's own URDF
parser (urdf_parser_py) reads them."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rftgls_conventions import LEG_JOINT_NAMES
from rftgls_core.description import DATA
from rftgls_core.description_writer import write_robot_description

PKG = Path(__file__).resolve().parents[1]
URI = 'package://minirquad_description/meshes/'
ROBOTS = ('minirquad', 'prototype')


@pytest.mark.parametrize('robot', ROBOTS)
def test_urdf_is_what_the_core_writes(robot, tmp_path):
    write_robot_description(robot, tmp_path, mesh_uri=URI)
    written = (tmp_path / f'{robot}.urdf').read_bytes()
    assert (PKG / 'urdf' / f'{robot}.urdf').read_bytes() == written
    assert (PKG / 'meshes' / 'c_leg.stl').read_bytes() == (tmp_path / 'c_leg.stl').read_bytes()
    # The core's own copy differs only in where the mesh is.
    core = (DATA / f'{robot}.urdf').read_text().replace('filename="c_leg.stl"',
                                                        f'filename="{URI}c_leg.stl"')
    assert core == (PKG / 'urdf' / f'{robot}.urdf').read_text()


@pytest.mark.parametrize('robot', ROBOTS)
def test_joints_links_and_inertia(robot):
    root = ET.parse(PKG / 'urdf' / f'{robot}.urdf').getroot()
    moving = {j.get('name'): j.get('type') for j in root.findall('joint')
              if j.get('type') != 'fixed'}
    assert moving == {n: 'continuous' for n in LEG_JOINT_NAMES}
    for mesh in root.iter('mesh'):
        fname = mesh.get('filename')
        assert fname.startswith(URI) and (PKG / 'meshes' / fname[len(URI):]).is_file()
    for link in root.findall('link'):
        if link.find('visual') is None and link.get('name') != 'base_link':
            continue                                  # a massless frame (imu_link, winch_link)
        i = link.find('inertial/inertia').attrib
        m = float(link.find('inertial/mass').get('value'))
        t = np.array([[i['ixx'], i['ixy'], i['ixz']], [i['ixy'], i['iyy'], i['iyz']],
                      [i['ixz'], i['iyz'], i['izz']]], dtype=float)
        ev = np.linalg.eigvalsh(t)
        assert m > 0 and ev.min() > 0, link.get('name')
        # Principal moments of a real body satisfy the triangle inequality.
        assert ev[0] + ev[1] >= ev[2] * (1 - 1e-6), link.get('name')


@pytest.mark.parametrize('robot', ROBOTS)
def test_ros_urdf_parser_reads_it(robot):
    from urdf_parser_py.urdf import URDF
    model = URDF.from_xml_string((PKG / 'urdf' / f'{robot}.urdf').read_text())
    assert model.get_root() == 'base_link'
    assert {j.name for j in model.joints if j.type == 'continuous'} == set(LEG_JOINT_NAMES)
