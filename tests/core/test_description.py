"""Anchor descriptions: the shipped URDF + YAML of each robot give the
numbers of `--robot` (1e-9), have the frames a ROS TF publisher needs, and bad descriptions
get one line."""
from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from tolerances import TWO_SOLVES_RTOL, TWO_SOLVES_TWIST_ATOL

from rftgls_core.cli.demo import ANCHOR_MODES
from rftgls_core.cli.main import main
from rftgls_core.description import (
    DATA,
    load_description,
    shipped_description,
    state_values,
)
from rftgls_core.description_writer import write_robot_description
from rftgls_core.posed import PosedAnchorSolver
from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.types import AnchorState, Pull

ROBOTS = ('prototype', 'minirquad')


@pytest.mark.parametrize('robot', ROBOTS)
def test_shipped_files_are_what_the_writer_writes(robot, tmp_path):
    write_robot_description(robot, tmp_path)
    for name in (f'{robot}.urdf', f'{robot}.yaml', 'c_leg.stl'):
        assert (tmp_path / name).read_bytes() == (DATA / name).read_bytes(), name


@pytest.mark.parametrize('robot', ROBOTS)
def test_urdf_has_the_frames_of_a_tf_publisher(robot):
    root = ET.parse(DATA / f'{robot}.urdf').getroot()
    links = {el.get('name') for el in root.findall('link')}
    assert {'base_link', 'imu_link', 'winch_link'} <= links
    hips = [j for j in root.findall('joint') if j.get('type') == 'continuous']
    assert len(hips) == 4
    assert all(j.find('parent').get('link') == 'base_link' for j in hips)
    assert {j.find('child').get('link') for j in hips} == {
        'left_proximal_leg', 'left_distal_leg', 'right_proximal_leg', 'right_distal_leg'}


@pytest.mark.parametrize('robot', ROBOTS)
def test_urdf_parses_with_a_standard_library(robot):
    """ROS's own URDF parser (urdf_parser_py, PyPI urdf-parser-py) reads the shipped URDF; the
    leg transforms composed from what it reads (base pose, joint origin, rotation about the
    joint axis with scipy's Rotation, mesh scale) place the leg mesh exactly where the robot
    preset's own posing (robots/robot.py, written independently of the URDF) puts it."""
    from scipy.spatial.transform import Rotation
    from urdf_parser_py.urdf import URDF

    from rftgls_core.geometry.stl import read_stl
    from rftgls_core.geometry.transforms import rot_y

    urdf = URDF.from_xml_file(str(DATA / f'{robot}.urdf'))
    assert urdf.name == robot
    assert {ln.name for ln in urdf.links} == {
        'base_link', 'imu_link', 'winch_link', 'left_proximal_leg', 'left_distal_leg',
        'right_proximal_leg', 'right_distal_leg'}
    joints = {j.name: j for j in urdf.joints}
    hips = ('leg_proximal_left', 'leg_distal_left', 'leg_proximal_right', 'leg_distal_right')
    assert {n for n, j in joints.items() if j.type == 'continuous'} == set(hips)
    assert {joints[n].type for n in ('imu_link_joint', 'winch_link_joint')} == {'fixed'}
    assert all(joints[h].parent == 'base_link' and joints[h].axis == [0.0, -1.0, 0.0]
               for h in hips)
    assert joints['winch_link_joint'].origin.xyz == [0.0, 0.0, 0.0]    # p is the tether point
    links = {ln.name: ln for ln in urdf.links}
    leg = read_stl(DATA / 'c_leg.stl', units='m')
    rob = get_robot(robot)
    for state in STATES:
        body = rot_y(-state.theta_b)
        p = np.array([0.0, 0.0, state.h])
        angle = {'proximal': state.theta_l1, 'distal': state.theta_l2}
        posed = {}
        for h in hips:
            j = joints[h]
            rot = body @ Rotation.from_euler('xyz', j.origin.rpy).as_matrix() \
                @ Rotation.from_rotvec(angle[h.split('_')[1]] * np.array(j.axis)).as_matrix()
            hip = p + body @ np.array(j.origin.xyz)
            scale = np.array(links[j.child].collision.geometry.scale)
            mesh = type(leg)(leg.vertices * scale, leg.faces if np.prod(scale) > 0
                             else leg.faces[:, ::-1])
            posed[h] = mesh.facets().transformed(rot, hip)
        # forward pulls use the leg mesh as it is (Pull.FORWARD, robots/robot.py)
        ref = rob.pose(state, Pull.FORWARD).facets
        ours = [posed[h] for h in hips]
        cent = np.vstack([f.centroids for f in ours])
        norm = np.vstack([f.normals for f in ours])
        # Two chains of rotations and translations (scipy's here, the preset's posing there)
        # of points ~0.1 m from the origin: a few roundings each, ~1e-17 m; normals are unit
        # vectors rounded the same way; areas are products of two such edges (a few eps).
        assert np.allclose(cent, ref.centroids, atol=1e-12)
        assert np.allclose(norm, ref.normals, atol=1e-12)
        assert np.allclose(np.concatenate([f.areas for f in ours]), ref.areas, rtol=1e-12)


# Table II poses (the demo's DH, DL, SH) and two more of the prototype's grid.
STATES = list(ANCHOR_MODES.values()) + [AnchorState.from_degrees(0.02, 0.0, -40.0, 0.0),
                                        AnchorState.from_degrees(0.015, 10.0, 20.0, -20.0)]


@pytest.mark.parametrize('robot', ROBOTS)
@pytest.mark.parametrize('method', ['twist-mesh', 'direct'])
def test_the_description_gives_the_numbers_of_the_robot(robot, method):
    desc = load_description(shipped_description(robot))
    medium = get_medium(desc.medium)
    reference = RobotPredictor(get_robot(robot), medium, method=method)
    solver = PosedAnchorSolver(medium, method=method)
    for state in STATES:
        for pull in Pull:
            for phi in (0.0, math.radians(-20.0)):
                a = reference.predict(state, phi, pull)
                b = solver.solve(desc.pose(state_values(state), pull), phi)
                assert b.space == 'sagittal' and a.status == b.status
                if a.capacity_N is None:
                    assert b.capacity_N is None
                    continue
                # the same problem from two posing paths (facets equal to 1e-12 m, above):
                # two solves, tests/tolerances.py
                assert b.capacity_N == pytest.approx(a.capacity_N, rel=TWO_SOLVES_RTOL,
                                                     abs=1e-12)
                t = np.array(b.slip_twist_scaled)
                assert np.allclose(t[[0, 2, 4]], a.slip_twist_scaled, atol=TWO_SOLVES_TWIST_ATOL)
                assert np.allclose(t[[1, 3, 5]], 0.0, atol=1e-12)


def test_cli_anchor_equals_cli_robot(capsys):
    dh = ['--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30',
          '--phi', '-20', '--json']
    assert main(['capacity', '--robot', 'minirquad', *dh]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main(['capacity', '--anchor', str(shipped_description('minirquad')), *dh]) == 0
    b = json.loads(capsys.readouterr().out)
    assert b['capacity_N'] == pytest.approx(a['capacity_N'], rel=TWO_SOLVES_RTOL)  # two solves


@pytest.fixture
def broken(tmp_path):
    """Copies of the shipped MiniRQuad description, each with one fault."""
    write_robot_description('minirquad', tmp_path)
    urdf = (tmp_path / 'minirquad.urdf').read_text()
    yml = (tmp_path / 'minirquad.yaml').read_text()
    (tmp_path / 'missing_mesh.urdf').write_text(urdf.replace('c_leg.stl', 'gone.stl'))
    (tmp_path / 'missing_mesh.yaml').write_text(yml.replace('minirquad.urdf',
                                                            'missing_mesh.urdf'))
    (tmp_path / 'no_range.yaml').write_text(yml.replace(
        '{name: theta_b, unit: deg, physical: [-90.0, 90.0],', '{name: theta_b, unit: deg,'))
    (tmp_path / 'bad_joint.yaml').write_text(yml.replace('leg_distal_left, ', 'knee, '))
    # One distal leg 1 mm further out than its mirror image: the claimed symmetry is false.
    (tmp_path / 'lopsided.urdf').write_text(urdf.replace('0.12 -0.055 0.01', '0.12 -0.056 0.01'))
    (tmp_path / 'lopsided.yaml').write_text(yml.replace('minirquad.urdf', 'lopsided.urdf'))
    return tmp_path


@pytest.mark.parametrize('case, expect', [
    ('missing_mesh', 'cannot read STL'),
    ('no_range', 'no physical range'),
    ('bad_joint', 'unknown joints knee'),
])
def test_bad_descriptions_are_one_line(broken, capsys, case, expect):
    code = main(['capacity', '--anchor', str(broken / f'{case}.yaml'), '--h', '0.034',
                 '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30', '--json'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and expect in err[0], err


def test_a_pose_outside_the_description_range_is_refused(capsys):
    code = main(['capacity', '--anchor', str(shipped_description('minirquad')), '--h', '3',
                 '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30'])
    err = capsys.readouterr().err
    assert code == 2 and 'outside' in err


def test_a_claimed_symmetry_is_checked(broken, capsys):
    args = ['capacity', '--anchor', str(broken / 'lopsided.yaml'), '--h', '0.034', '--theta-b',
            '5', '--theta-l1', '-40', '--theta-l2', '30', '--json']
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    assert res['status'] == 'invalid_input' and res['reason'] == 'not_symmetric'
    assert res['capacity_N'] is None
    # without the claim the lopsided robot is simply answered in 6D
    (broken / 'unclaimed.yaml').write_text(
        (broken / 'lopsided.yaml').read_text().replace('symmetry: sagittal', ''))
    assert main([*args[:2], str(broken / 'unclaimed.yaml'), *args[3:]]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res['status'] == 'ok' and res['method'] == 'direct-6d'
