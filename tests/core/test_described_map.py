"""Maps over the state variables a description declares: a two-variable ellipsoid
anchor gets a two-axis map, the shipped MiniRQuad description a map whose nodes are the robot's
live answers, and a map refuses another description."""
from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from tolerances import INTERPOLATION_ATOL, INTERPOLATION_RTOL

from rftgls_core.cli.main import main
from rftgls_core.description import (
    load_description,
    shipped_description,
    state_values,
)
from rftgls_core.description_writer import write_robot_description
from rftgls_core.geometry.shapes import ellipsoid
from rftgls_core.geometry.stl import write_stl
from rftgls_core.maps import CapacityMap, MapFileError, resolve_map
from rftgls_core.maps.described import (
    DescribedMap,
    description_grid,
    save_described_map,
)
from rftgls_core.maps.described_build import build_described_map
from rftgls_core.posed import PosedAnchorSolver
from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
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
    # A node of the map is the live answer of the same posed anchor (float32 storage).
    live = PosedAnchorSolver(medium, space='sagittal')
    node = {'depth': -0.04, 'tilt': math.radians(10.0)}
    want = live.solve(desc.pose(node), math.radians(90.0), 0.0)
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
    robot = RobotPredictor(get_robot('minirquad'), medium, method='twist-mesh')
    dh = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)   # Table II, DH
    for j, phi in enumerate(grid.phi):
        r = robot.predict(dh, float(phi), 'backward')
        assert r.capacity_N is not None
        assert float(data.capacity_N[0, 0, 0, 0, 1, j]) == pytest.approx(r.capacity_N, rel=1e-6)
    cmap = DescribedMap(data)
    q = cmap.query(state_values(dh), math.radians(-20.0), 'backward', desc.sha256)
    # on a node every weight is 0 or 1: the stored value itself
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


# ------------------------------------------------ described maps in every tool
@pytest.fixture
def box_map(box_anchor, tmp_path):
    """The box anchor over depth -50..-30 mm (3) and tilt 0..10 deg (2), phi 0, 45, 90 deg."""
    desc = load_description(box_anchor / 'box.yaml')
    grid = description_grid(desc, phi_deg=[0.0, 45.0, 90.0])
    data = build_described_map(desc, get_medium('glass_beads'), grid, method='twist-mesh')
    return save_described_map(tmp_path / 'box.h5', data), desc


def test_parallel_build_gives_the_same_map(box_anchor):
    """Two worker processes (spawned, each re-reading the description and checking its
    identity) give the arrays of the in-process build, bit for bit."""
    from rftgls_core.maps.described import content_sha256
    desc = load_description(box_anchor / 'box.yaml')
    grid = description_grid(desc, {'depth': [-0.05, -0.04, -0.03]}, [0.0, 90.0])
    one = build_described_map(desc, get_medium('glass_beads'), grid, method='twist-mesh')
    two = build_described_map(desc, get_medium('glass_beads'), grid, method='twist-mesh',
                              workers=2)
    assert content_sha256(one) == content_sha256(two)
    assert np.array_equal(one.capacity_N, two.capacity_N, equal_nan=True)


def test_batch_query_is_the_single_query(box_map):
    """query_batch (plots) gives query's capacity and status at random points, inside the
    grid, on nodes and off it."""
    path, desc = box_map
    cmap = DescribedMap.load(path)
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-0.055, -0.025, 60), rng.uniform(-0.02, 0.2, 60)])
    pts[:3] = [[-0.05, 0.0], [-0.04, math.radians(10.0)], [-0.03, 0.0]]     # nodes
    phi = math.radians(30.0)
    cap, code = cmap.query_batch(pts, phi, 'backward', desc.sha256)
    from rftgls_core.maps.hdf5 import STATUS_NAMES
    seen = set()
    for (d, t), c, k in zip(pts, cap, code):
        q = cmap.query({'depth': d, 'tilt': t}, phi, 'backward', desc.sha256)
        assert STATUS_NAMES[k] == q.status.value
        seen.add(q.status)
        if q.capacity_N is None:
            assert math.isnan(c)
        else:
            # single against batched query (tests/tolerances.py)
            assert c == pytest.approx(q.capacity_N, rel=INTERPOLATION_RTOL, abs=INTERPOLATION_ATOL)
    assert seen == {Status.OK, Status.OUT_OF_RANGE}
    with pytest.raises(ValueError, match='built for description'):
        cmap.query_batch(pts, phi, 'backward', 'f' * 64)


def test_cli_accuracy_refine_and_plot_take_a_described_map(box_map, box_anchor, tmp_path,
                                                           capsys):
    path, desc = box_map
    yaml = str(box_anchor / 'box.yaml')
    assert main(['map', 'accuracy', str(path), '--anchor', yaml, '--samples', '2',
                 '--reference', 'twist-mesh', '--json', '--quiet']) == 0
    import json
    rep = json.loads(capsys.readouterr().out)
    # the reference is the build's own method: between nodes only interpolation differs,
    # and both answer everywhere inside the grid
    assert rep['n_states'] == 4 and rep['n_compared'] == 4 * 2 and rep['status_mismatch'] == 0
    assert 0.0 < rep['capacity_pct']['worst'] < 20.0
    assert main(['map', 'refine', str(path), '--anchor', yaml, '--out', str(tmp_path / 'r.h5'),
                 '--tol', '0', '--samples', '2', '--quiet', '--workers', '1']) == 0
    out = capsys.readouterr().out
    assert '6 -> 15 states (+9)' in out            # a midpoint in every interval (tol 0)
    r = DescribedMap.load(tmp_path / 'r.h5')
    assert r.grid.state_shape == (5, 3)
    assert np.allclose(r.grid.axes[1], np.radians([0.0, 5.0, 10.0]))
    assert '--axis=depth=' in r.data.attrs['build_command']
    png = tmp_path / 'slice.png'
    assert main(['map', 'plot', str(path), '--x', 'depth', '--y', 'tilt', '--n', '20',
                 '--out', str(png)]) == 0
    assert png.stat().st_size > 10_000
    assert '400 of 400 pixels with a value' in capsys.readouterr().out


@pytest.mark.parametrize('argv, must', [
    (['map', 'accuracy', 'BOX'], '--anchor FILE.yaml'),
    (['map', 'accuracy', 'BOX', '--anchor', 'MINI'], 'was built for description box_anchor'),
    (['map', 'accuracy', 'BOX', '--anchor', 'YAML', '--random', '5'], '--samples'),
    (['map', 'refine', 'BOX', '--out', 'OUT'], '--anchor FILE.yaml'),
    (['map', 'accuracy', 'minirquad', '--anchor', 'YAML'], 'for described maps'),
    (['map', 'plot', 'BOX', '--x', 'depth', '--y', 'depth', '--out', 'OUT'], 'two different'),
    (['map', 'plot', 'BOX', '--x', 'depth', '--y', 'tilt', '--at', 'tilt=5', '--out', 'OUT'],
     'is plotted'),
    (['map', 'plot', 'BOX', '--x', 'depth', '--y', 'tilt', '--at', 'h=5', '--out', 'OUT'],
     'NAME one of depth, tilt'),
    (['map', 'plot', 'BOX', '--x', 'depth', '--y', 'tilt', '--h', '30', '--out', 'OUT'],
     'described map'),
    (['map', 'plot', 'minirquad', '--x', 'depth', '--out', 'OUT'], '--x must be one of'),
])
def test_described_map_tools_refuse_in_one_line(argv, must, box_map, box_anchor, tmp_path,
                                                capsys):
    path, _ = box_map
    subst = {'BOX': str(path), 'YAML': str(box_anchor / 'box.yaml'),
             'MINI': str(shipped_description('minirquad')), 'OUT': str(tmp_path / 'x.h5')}
    code = main([subst.get(a, a) for a in argv])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(err) == 1 and must in err[0], err
    assert not (tmp_path / 'x.h5').exists()


def test_accuracy_is_honest_next_to_nodes_without_a_value(box_anchor, tmp_path):
    """A grid reaching past the physical range (depth > 0: `not_a_pose`, no value): the map
    withholds its value in every cell that touches such a node, where the live reference
    still answers; it never answers where the reference does not."""
    from rftgls_core.maps.described_accuracy import described_accuracy
    desc = load_description(box_anchor / 'box.yaml')
    grid = description_grid(desc, {'depth': [-0.03, -0.01, 0.01]}, [0.0, 90.0])
    data = build_described_map(desc, get_medium('glass_beads'), grid, method='twist-mesh')
    from rftgls_core.maps.hdf5 import STATUS_NAMES
    assert (data.status[0, 2] == STATUS_NAMES.index('invalid_input')).all()
    cmap = DescribedMap(data, source='edge.h5')
    rep = described_accuracy(cmap, desc, samples=6, reference='twist-mesh')
    assert rep.map_conservative > 0                      # the reference answered, the map not
    assert rep.status_mismatch == rep.map_conservative   # never a value the reference lacks


def test_support_edge_rules_of_the_robot_maps(box_map):
    """One node made `unsupported`: next to the valued corners (their weight >= 0.9) the cell
    answers their renormalised blend ('edge_valued'); mid-cell it withholds the value as
    `unsupported`, unless the opt-in zeros rule counts the node as 0 N ('support_edge').
    Reference values: the blends computed here by hand from the node values."""
    import copy

    from rftgls_core.maps.hdf5 import STATUS_NAMES
    path, desc = box_map
    data = copy.deepcopy(DescribedMap.load(path).data)
    # depth nodes -0.05, -0.04, -0.03; tilt 0, 10 deg; phi 0, 45, 90 deg
    data.status[0, 0, 1, :] = STATUS_NAMES.index('unsupported')   # (-0.05 m, 10 deg)
    cap = data.capacity_N[0].astype(float)
    phi = 0.0
    for support_edge in (False, True):
        cmap = DescribedMap(data, support_edge=support_edge)
        # 95 % of the way to the valued corner (-0.05, 0), 5 % toward (-0.04, ...)
        t = math.radians(10.0) * 0.02
        q = cmap.query({'depth': -0.0495, 'tilt': t}, phi, 'backward', desc.sha256)
        wd, wt = 0.05, 0.02
        w = {(0, 0): (1 - wd) * (1 - wt), (1, 0): wd * (1 - wt), (1, 1): wd * wt}
        want = sum(v * cap[i, j, 0] for (i, j), v in w.items()) / sum(w.values())
        assert q.status is Status.OK and q.flags == ('edge_valued',)
        # the same three-corner weighted mean computed by hand: a few eps per weight and term
        assert q.capacity_N == pytest.approx(want, rel=1e-9)
        mid = cmap.query({'depth': -0.045, 'tilt': math.radians(5.0)}, phi, 'backward',
                         desc.sha256)
        if support_edge:
            zeros = 0.25 * (cap[0, 0, 0] + cap[1, 0, 0] + cap[1, 1, 0])
            assert mid.status is Status.OK and mid.flags == ('support_edge',)
            assert mid.capacity_N == pytest.approx(zeros, rel=1e-9)
        else:
            assert mid.status is Status.UNSUPPORTED and mid.capacity_N is None
        pts = np.array([[-0.0495, t], [-0.045, math.radians(5.0)]])
        c, code = cmap.query_batch(pts, phi, 'backward', desc.sha256)
        assert c[0] == pytest.approx(want, rel=INTERPOLATION_RTOL)   # batched, as above
        assert STATUS_NAMES[code[1]] == mid.status.value


@pytest.mark.parametrize('space', ['sagittal', '6d'])
def test_one_fit_per_node_gives_the_one_by_one_answers(box_anchor, space):
    """PosedAnchorSolver.predict_many (the map build's one fit per node and pull) equals predict at
    each angle, on the sagittal and the 6D path, with a non-finite angle answered alone."""
    desc = load_description(box_anchor / 'box.yaml')
    posed = desc.pose({'depth': -0.04, 'tilt': math.radians(10.0)})
    sm = PosedAnchorSolver(get_medium('glass_beads'), method='twist-mesh', space=space)
    phis = [math.radians(a) for a in (-30.0, 0.0, 45.0, 90.0)] + [math.nan]
    many = sm.solve_many(posed, phis)
    assert many[-1].status is Status.INVALID_INPUT and many[-1].reason == 'invalid_phi'
    for phi, r in zip(phis[:-1], many):
        one = sm.solve(posed, phi)
        assert r.status is one.status is Status.OK and r.space == one.space
        assert r.capacity_N == one.capacity_N and r.slip_twist == one.slip_twist
