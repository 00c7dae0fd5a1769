"""Writing the shipped anchor descriptions of the robot presets: the one source of the robots'
URDF.

`write_robot_description(robot, folder)` writes <robot>.urdf, <robot>.yaml and the leg mesh
c_leg.stl from robots/presets.py. The core's own copies (rftgls_core/data) have the mesh next
to the URDF; the ROS description package (src/minirquad_description: share/.../urdf and
meshes) is the same document with `mesh_uri='package://minirquad_description/meshes/'`, the
form RViz resolves. Tests regenerate both and compare them byte for byte, so the core (ROS-free,
installable alone) and robot_state_publisher, RViz and the capacity all see one robot.

URDF conventions: base_link = body frame B (origin at the winch point p); one link per leg on
a `continuous` hip joint named as the driver's /joint_states (rftgls_conventions:
leg_proximal_left, ...), axis -y_B so the joint value is the paper's leg angle; imu_link and
winch_link are fixed frames without mass. Masses: the paper gives the total only, so each leg
is ASSUMED to weigh LEG_MASS_KG with its mass centre on its hip axis, and base_link carries the
rest at the preset's centre of mass. The hips sit symmetrically about that centre (x midway
between the axles, at axle height, y mirrored), so the robot's total mass and centre of mass
are the preset's at every leg angle and the capacity is unchanged; the split only matters to
tools that use inertia (a physics simulator). Inertia tensors are of uniform solids: each leg
from its closed mesh (about the hip point, in the leg frame), base_link an ASSUMED box.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rftgls_conventions import LEG_JOINT_NAMES
from rftgls_conventions.safe_write import write_text

from .geometry.mesh import TriMesh
from .geometry.stl import write_stl

# Map ranges the written descriptions carry (start, stop, count; m and deg), for a map built
# from the description. The preset robots' own maps (maps/grid.py) reach further in thetaL2
# and, for MiniRQuad, thetaB: the planner's final poses and predicted pitches.
MAP_RANGES = {
    'prototype': {'h': (0.005, 0.030, 6), 'theta_b': (-20, 20, 5), 'theta_l1': (-40, 40, 5),
                  'theta_l2': (-40, 40, 5)},
    'minirquad': {'h': (0.025, 0.055, 7), 'theta_b': (-5, 15, 5), 'theta_l1': (-60, 0, 4),
                  'theta_l2': (-20, 40, 7)},
}
# (leg link prefix, axle 0 proximal / 1 distal, side +1 left / -1 right, /joint_states name)
LEGS = tuple((leg, axle, side, f'leg_{leg.split("_")[1]}_{leg.split("_")[0]}')
             for leg, axle, side in (('left_proximal', 0, +1), ('left_distal', 1, +1),
                                     ('right_proximal', 0, -1), ('right_distal', 1, -1)))
assert {j for *_, j in LEGS} == set(LEG_JOINT_NAMES)
LEG_MASS_KG = 0.005        # ASSUMED: one printed C-leg with its hub (not in the paper)
BASE_HEIGHT_M = 0.02       # ASSUMED: height of the box base_link's inertia is computed for


def solid_inertia(mesh: TriMesh, mass: float) -> np.ndarray:
    """(3, 3) inertia tensor (kg m^2) about the mesh frame's origin of a uniform solid of
    `mass` bounded by the closed, outward-wound `mesh` (tetrahedra from the origin: each
    contributes det(A) A C0 A^T to the second moment, C0 the unit tetrahedron's)."""
    tri = mesh.vertices[mesh.faces]                       # (F, 3, 3): a, b, c
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    det = np.einsum('ij,ij->i', a, np.cross(b, c))       # 6 x signed tetra volume
    c0 = np.full((3, 3), 1.0) + np.eye(3)                 # 120 x unit-tetra covariance
    mats = np.stack([a, b, c], axis=2)                    # columns a, b, c
    second = np.einsum('f,fik,kl,fjl->ij', det, mats, c0, mats) / 120.0
    volume = det.sum() / 6.0
    if not volume > 0:
        raise ValueError('leg mesh is not a closed outward-wound solid')
    second *= mass / volume
    return np.trace(second) * np.eye(3) - second


def box_inertia(mass: float, dx: float, dy: float, dz: float) -> np.ndarray:
    return mass / 12.0 * np.diag([dy * dy + dz * dz, dx * dx + dz * dz, dx * dx + dy * dy])


def _digits(x: float, scale: float) -> str:
    """x to 6 significant digits, 0 below 1e-9 of `scale` (the tensor's largest entry). The
    sums behind an inertia differ in their last bits between CPUs (SIMD summation order,
    docs/design/numerics.md); rounding far above that noise keeps the written file the same
    on every machine (a value within 1e-16 of a 6-digit rounding edge: odds ~1e-10)."""
    return '0' if abs(x) < 1e-9 * scale else f'{float(x):.6g}'


def _inertial(xyz, mass: float, inertia: np.ndarray) -> str:
    r = repr
    top = float(np.max(np.abs(inertia)))
    i = [[_digits(v, top) for v in row] for row in inertia]
    return (f'<inertial><origin xyz="{r(float(xyz[0]))} {r(float(xyz[1]))} '
            f'{r(float(xyz[2]))}" rpy="0 0 0"/>'
            f'<mass value="{r(mass)}"/><inertia ixx="{i[0][0]}" ixy="{i[0][1]}" '
            f'ixz="{i[0][2]}" iyy="{i[1][1]}" iyz="{i[1][2]}" izz="{i[2][2]}"/>'
            '</inertial>')


def write_robot_description(name: str, folder: str | Path, mesh_uri: str = '') -> Path:
    """Write <name>.urdf, <name>.yaml and the leg mesh (ASCII STL, full precision) for a robot
    preset into folder; returns the YAML path. Mesh filenames are `mesh_uri` + 'c_leg.stl'
    ('' = next to the URDF). See the module doc for frames, joints and masses."""
    from .robots.presets import get_robot
    robot = get_robot(name)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    leg_file = 'c_leg.stl'
    write_stl(folder / leg_file, robot.leg_mesh, units='m', ascii=True, name='c_leg')
    r = repr

    def origin(x, y, z):
        return f'<origin xyz="{r(x)} {r(y)} {r(z)}" rpy="0 0 0"/>'
    base_mass = robot.mass - 4 * LEG_MASS_KG
    base_inertia = box_inertia(base_mass, robot.plate_length, 2 * min(robot.leg_y),
                               BASE_HEIGHT_M)
    lines = ['<?xml version="1.0"?>',
             f'<!-- {name}: written by rftgls_core.description_writer.write_robot_description '
             'from robots/presets.py; the numbers the paper does not give are assumptions '
             'there and in the writer (leg masses, base inertia) -->',
             f'<robot name="{name}">',
             '  <link name="base_link">',
             f'    {_inertial((robot.com[0], 0.0, robot.com[1]), base_mass, base_inertia)}',
             '  </link>']
    for leg, axle, side, joint in LEGS:
        scale = np.array([1.0, float(side), 1.0])
        mesh = TriMesh(robot.leg_mesh.vertices * scale,
                       robot.leg_mesh.faces if side > 0 else robot.leg_mesh.faces[:, ::-1])
        geometry = (f'<geometry><mesh filename="{mesh_uri}{leg_file}" '
                    f'scale="{"1 1 1" if side > 0 else "1 -1 1"}"/></geometry>')
        inertial = _inertial((0.0, 0.0, 0.0), LEG_MASS_KG, solid_inertia(mesh, LEG_MASS_KG))
        lines += [f'  <link name="{leg}_leg">',
                  f'    {inertial}',
                  f'    <visual>{geometry}</visual>',
                  f'    <collision>{geometry}</collision>',
                  '  </link>',
                  f'  <joint name="{joint}" type="continuous">',
                  '    <parent link="base_link"/>',
                  f'    <child link="{leg}_leg"/>',
                  f'    {origin(robot.axle_x[axle], side * robot.leg_y[axle], robot.axle_z)}',
                  '    <axis xyz="0 -1 0"/>',
                  '    <limit effort="1" velocity="10"/>',
                  '  </joint>']
    for link, xyz in (('imu_link', (0.5 * sum(robot.axle_x), 0.0, robot.axle_z)),
                      ('winch_link', (0.0, 0.0, 0.0))):
        lines += [f'  <link name="{link}"/>',
                  f'  <joint name="{link}_joint" type="fixed">',
                  '    <parent link="base_link"/>',
                  f'    <child link="{link}"/>',
                  f'    {origin(*xyz)}',
                  '  </joint>']
    lines.append('</robot>')
    write_text(folder / f'{name}.urdf', '\n'.join(lines) + '\n')
    write_text(folder / f'{name}.yaml', _yaml(name, robot))
    return folder / f'{name}.yaml'


def _yaml(name: str, robot) -> str:
    r = repr
    sr = robot.state_range
    deg = 180.0 / math.pi
    mr = MAP_RANGES[name]
    joints = {axle: ', '.join(j for _, a, _, j in LEGS if a == axle) for axle in (0, 1)}

    def rng(lo, hi):
        return f'[{r(lo)}, {r(hi)}]'
    legs = rng(sr.theta_leg[0] * deg, sr.theta_leg[1] * deg)
    return f"""# Anchor description of {name} (docs/design/six-d.md, "Anchor descriptions").
# Written by rftgls_core.description_writer.write_robot_description; the URDF holds links,
# meshes, joints and inertials, this file what URDF has no place for.
name: {name}
urdf: {name}.urdf
tether_link: winch_link
char_length_m: {r(robot.char_length)}
medium: {'glass_beads' if name == 'prototype' else 'm90_sand'}
symmetry: sagittal    # claimed mirror symmetry about x-z of base_link: checked at every pose
base_pose:            # base_link origin at height h, turned by rot_y(-theta_b)
  height: h
  pitch: theta_b
surface_points:       # the body plate's ends in base_link, m: a slip stops when one reaches z = 0
  - [0.0, 0.0, 0.0]
  - [{r(robot.plate_length)}, 0.0, 0.0]
pull_scale:           # the paper's C-leg orientation (types.Pull), in the leg frames
  forward: [1.0, 1.0, 1.0]
  backward: [-1.0, 1.0, 1.0]
  links: [{', '.join(f'{leg}_leg' for leg, *_ in LEGS)}]
state:                # physical: the range a pose can be in; map: start, stop, count
  - {{name: h, unit: m, physical: {rng(*sr.h)}, map: {list(mr['h'])}}}
  - {{name: theta_b, unit: deg, physical: {rng(sr.theta_b[0] * deg, sr.theta_b[1] * deg)}, map: {list(mr['theta_b'])}}}
  - {{name: theta_l1, unit: deg, joints: [{joints[0]}], physical: {legs}, map: {list(mr['theta_l1'])}}}
  - {{name: theta_l2, unit: deg, joints: [{joints[1]}], physical: {legs}, map: {list(mr['theta_l2'])}}}
"""  # noqa: E501
