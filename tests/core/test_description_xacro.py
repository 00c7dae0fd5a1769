"""Anchor descriptions from xacro (a URDF is read with xacro expanded): a
`*.urdf.xacro` file is expanded with the xacro package before it is read. The reference is the
plain URDF of the same body, examples/anchors/ellipsoid.urdf, written by hand: the xacro
version below builds the same link from a macro and properties, and must give the same
capacity and slip twist; its identity does not depend on where the files lie; a xacro that
does not expand is one line and exit 2."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rftgls_core.cli.main import main
from rftgls_core.description import (
    DescriptionError,
    description_sha256,
    load_description,
)

pytest.importorskip('xacro')

FOLDER = Path(__file__).resolve().parents[2] / 'examples' / 'anchors'
XACRO = """<?xml version="1.0"?>
<robot name="ellipsoid_anchor" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:property name="mass" value="0.040"/>
  <xacro:property name="mm" value="0.001"/>
  <xacro:macro name="rigid_body" params="name mesh">
    <link name="${name}">
      <inertial>
        <origin xyz="${30 * mm} 0 0" rpy="0 0 0"/>
        <mass value="${mass}"/>
        <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/>
      </inertial>
      <collision><geometry><mesh filename="${mesh}" scale="${mm} ${mm} ${mm}"/></geometry>
      </collision>
    </link>
  </xacro:macro>
  <xacro:rigid_body name="base_link" mesh="ellipsoid.stl"/>
  <link name="winch_link"/>
  <joint name="winch_joint" type="fixed">
    <parent link="base_link"/>
    <child link="winch_link"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
  </joint>
</robot>
"""


def xacro_description(folder: Path, text: str = XACRO) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(FOLDER / 'ellipsoid.stl', folder / 'ellipsoid.stl')
    (folder / 'ellipsoid.urdf.xacro').write_text(text)
    yaml_text = (FOLDER / 'ellipsoid.yaml').read_text().replace('urdf: ellipsoid.urdf',
                                                                'urdf: ellipsoid.urdf.xacro')
    assert 'ellipsoid.urdf.xacro' in yaml_text
    (folder / 'ellipsoid.yaml').write_text(yaml_text)
    return folder / 'ellipsoid.yaml'


def capacity(capsys, yaml_path: Path) -> dict:
    assert main(['capacity', '--anchor', str(yaml_path), '--state', 'depth=-0.055',
                 '--state', 'tilt=-30', '--phi', '45', '--json']) == 0
    return json.loads(capsys.readouterr().out)


def test_a_xacro_description_is_its_plain_urdf(tmp_path, capsys):
    plain = capacity(capsys, FOLDER / 'ellipsoid.yaml')
    expanded = capacity(capsys, xacro_description(tmp_path / 'a'))
    assert plain['status'] == expanded['status'] == 'ok'
    assert expanded['capacity_N'] == pytest.approx(plain['capacity_N'], rel=1e-12)
    assert expanded['slip_twist_scaled'] == pytest.approx(plain['slip_twist_scaled'], abs=1e-12)
    desc = load_description(tmp_path / 'a' / 'ellipsoid.yaml')
    assert '<mass value="0.04"/>' in desc.urdf_text()     # robot_description: expanded
    assert 'xacro:' not in desc.urdf_text()


def test_its_identity_does_not_depend_on_the_folder(tmp_path):
    a = description_sha256(xacro_description(tmp_path / 'a'))
    b = description_sha256(xacro_description(tmp_path / 'elsewhere' / 'b'))
    changed = description_sha256(xacro_description(
        tmp_path / 'c', XACRO.replace('value="0.040"', 'value="0.041"')))
    assert a == b != changed


def test_a_xacro_that_does_not_expand_is_one_line(tmp_path, capsys):
    bad = xacro_description(tmp_path / 'bad', XACRO.replace('${mass}', '${no_such_property}'))
    with pytest.raises(DescriptionError, match='xacro cannot expand it'):
        load_description(bad)
    assert main(['capacity', '--anchor', str(bad), '--state', 'depth=-0.055',
                 '--state', 'tilt=-30', '--phi', '45', '--json']) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'no_such_property' in err, err
