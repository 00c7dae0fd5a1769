"""Maps over the state variables a description declares (issue 12, item 7): a two-variable ellipsoid
anchor gets a two-axis map, the shipped MiniRQuad description a map whose nodes are the robot's
live answers, and a map refuses another description."""
from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from rftgls_core.anchor import AnchorModel
from rftgls_core.cli.main import main
from rftgls_core.description import (
    load_description,
    shipped_description,
    state_values,
    write_robot_description,
)
from rftgls_core.geometry.shapes import ellipsoid
from rftgls_core.geometry.stl import write_stl
from rftgls_core.maps import CapacityMap, MapFileError, resolve_map
from rftgls_core.maps.described import (
    DescribedMap,
    build_described_map,
    description_grid,
    save_described_map,
)
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.scene import SceneModel
from rftgls_core.types import AnchorState, Status

BOX_URDF = """<?xml version="1.0"?>
<robot name="box_anchor">
  <link name="base_link">
    <inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="0.2"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>
    <collision><geometry><mesh filename="box.stl"/></geometry></collision>
  </link>
  <link name="winch_link"/>
  <joint name="winch_joint" type="fixed">
    <parent link="base_link"/><child link="winch_link"/>
    <origin xyz="0 0 0.01" rpy="0 0 0"/>
  </joint>
</robot>
"""
BOX_YAML = """name: box_anchor
urdf: box.urdf
tether_link: winch_link
char_length_m: 0.04
medium: glass_beads
symmetry: sagittal
base_pose: {height: depth, pitch: tilt}
state:
  - {name: depth, unit: m, physical: [-0.2, 0.0], map: [-0.05, -0.03, 3]}
  - {name: tilt, unit: deg, physical: [-45, 45]TILT_MAP}
"""


@pytest.fixture
def box_anchor(tmp_path):
    """An ellipsoid (semi-axes 20, 15, 10 mm; mirror-symmetric facets, so the sagittal claim
    holds) with two state variables: depth of its centre (m) and tilt (deg)."""
    write_stl(tmp_path / 'box.stl', ellipsoid(0.02, 0.015, 0.01, subdivisions=2), units='m')
    (tmp_path / 'box.urdf').write_text(BOX_URDF)
    (tmp_path / 'box.yaml').write_text(BOX_YAML.replace('TILT_MAP', ', map: [0, 10, 2]'))
    (tmp_path / 'no_range.yaml').write_text(BOX_YAML.replace('TILT_MAP', ''))
    return tmp_path


def test_a_box_map_has_the_description_axes_and_the_live_answers(box_anchor, tmp_path):
    desc = load_description(box_anchor / 'box.yaml')
    medium = get_medium('glass_beads')
    grid = description_grid(desc, phi_deg=[0.0, 90.0])
    assert grid.names == ('depth', 'tilt') and grid.state_shape == (3, 2)
    assert grid.pulls == ('backward',)         # no C-legs: one orientation
    out = save_described_map(tmp_path / 'box.h5', build_described_map(desc, medium, grid))
    with h5py.File(out, 'r') as f:
        assert sorted(f['axes']) == ['depth', 'phi', 'pull', 'tilt']
        assert f['capacity_N'].shape == (1, 3, 2, 2)
        assert f['axes/tilt'].attrs['human_unit'] == 'deg'
        assert np.allclose(f['axes/tilt'][()], [0.0, math.radians(10.0)])
    cmap = DescribedMap.load(out)
    # A node of the map is the live answer of the same scene (float32 storage).
    live = SceneModel(medium, space='sagittal')
    node = {'depth': -0.04, 'tilt': math.radians(10.0)}
    want = live.predict(desc.scene(node), math.radians(90.0), 0.0)
    got = cmap.query(node, math.radians(90.0), 'backward', desc.sha256)
    assert want.status is Status.OK and got.status is Status.OK
    assert got.capacity_N == pytest.approx(want.capacity_N, rel=1e-6)
    assert got.slip_twist_scaled == pytest.approx(want.slip_twist_scaled, abs=1e-6)
    assert got.slip_twist == pytest.approx(want.slip_twist, abs=1e-6)
    # Deeper holds more (RFT stress grows with depth), and half-way between two nodes the map
    # answers their mean.
    a, b = (cmap.query({'depth': d, 'tilt': 0.0}, 0.0, 'backward', desc.sha256).capacity_N
            for d in (-0.05, -0.04))
    mid = cmap.query({'depth': -0.045, 'tilt': 0.0}, 0.0, 'backward', desc.sha256)
    assert a > b and mid.capacity_N == pytest.approx(0.5 * (a + b), rel=1e-6)
    off = cmap.query({'depth': -0.06, 'tilt': 0.0}, 0.0, 'backward', desc.sha256)
    assert off.status is Status.OUT_OF_RANGE and off.capacity_N is None
    # Another description (the MiniRQuad's) is refused, without a number.
    other = load_description(shipped_description('minirquad')).sha256
    refused = cmap.query(node, 0.0, 'backward', other)
    assert refused.status is Status.INVALID_INPUT and refused.reason == 'description_mismatch'
    assert refused.capacity_N is None
    # A changed value is caught by the content hash.
    with h5py.File(out, 'r+') as f:
        f['capacity_N'][0, 0, 0, 0] *= 2.0
    with pytest.raises(MapFileError, match='content_sha256'):
        DescribedMap.load(out)


def test_the_identity_follows_the_files_not_their_place(box_anchor, tmp_path):
    write_robot_description('minirquad', tmp_path / 'copy')
    a = load_description(shipped_description('minirquad')).sha256
    assert load_description(tmp_path / 'copy' / 'minirquad.yaml').sha256 == a
    stl = box_anchor / 'box.stl'
    before = load_description(box_anchor / 'box.yaml').sha256
    write_stl(stl, ellipsoid(0.02, 0.015, 0.011, subdivisions=2), units='m')   # a changed mesh
    assert load_description(box_anchor / 'box.yaml').sha256 != before


def test_the_shipped_description_map_holds_the_robot_answers(tmp_path):
    desc = load_description(shipped_description('minirquad'))
    medium = get_medium('m90_sand')
    grid = description_grid(desc, {'h': [0.034, 0.036], 'theta_b': [5.0, 8.9],
                                   'theta_l1': [-40.0, -20.0], 'theta_l2': [20.0, 30.0]},
                            [-20.0, 0.0], ('backward',))
    data = build_described_map(desc, medium, grid, method='twist-mesh')
    robot = AnchorModel(get_robot('minirquad'), medium, method='twist-mesh')
    dh = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)   # Table II, DH
    for j, phi in enumerate(grid.phi):
        r = robot.predict(dh, float(phi), 'backward')
        assert r.capacity_N is not None
        assert float(data.capacity_N[0, 0, 0, 0, 1, j]) == pytest.approx(r.capacity_N, rel=1e-6)
    cmap = DescribedMap(data)
    q = cmap.query(state_values(dh), math.radians(-20.0), 'backward', desc.sha256)
    assert q.capacity_N == pytest.approx(float(data.capacity_N[0, 0, 0, 0, 1, 0]), rel=1e-9)


def test_cli_builds_an_anchor_map_and_refuses_a_missing_range(box_anchor, tmp_path, capsys):
    out = tmp_path / 'cli.h5'
    assert main(['map', 'build', '--anchor', str(box_anchor / 'box.yaml'), '--medium',
                 'glass_beads', '--out', str(out), '--axis', 'depth=-0.05,-0.04',
                 '--phi=0,90', '--quiet']) == 0
    assert 'depth -0.05..-0.04 m (2), tilt 0..10 deg (2)' in capsys.readouterr().out
    assert DescribedMap.load(out).grid.state_shape == (2, 2)
    assert main(['map', 'info', str(out)]) == 0
    info = capsys.readouterr().out
    assert 'description box_anchor' in info and 'tilt      [rad]  2 nodes: 0 10 deg' in info
    code = main(['map', 'build', '--anchor', str(box_anchor / 'no_range.yaml'), '--out',
                 str(tmp_path / 'x.h5'), '--quiet'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and 'tilt' in err[0] and 'no map range' in err[0]


def test_a_robot_map_answers_for_its_shipped_description_only():
    cmap = CapacityMap.load(resolve_map('minirquad'))
    cmap.check_description(load_description(shipped_description('minirquad')).sha256)
    with pytest.raises(ValueError, match='not for description'):
        cmap.check_description(load_description(shipped_description('prototype')).sha256)
