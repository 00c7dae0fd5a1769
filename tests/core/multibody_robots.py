"""A described robot for the multibody tests: not a preset (its own legs, base, mass, axles),
written as URDF + YAML + STL into a folder, as a user would write one."""
from __future__ import annotations

from pathlib import Path

from rftgls_core.geometry.shapes import box, c_leg
from rftgls_core.geometry.stl import write_stl

# A 200 g robot with a 120 x 70 x 12 mm box body and four C-legs of 70 mm diameter, 8 mm
# wide, on axles 25 and 95 mm from its tether point, 4 mm under the body, the legs outside the
# body (|y| 45 mm).
LEG = dict(arc_diameter=0.070, thickness=0.004, width=0.008, n_arc=16)
BODY = (0.120, 0.070, 0.012)


def write_robot(folder: Path, leg_y: float = 0.045, limits: tuple[float, float] | None = None,
                base_mesh: bool = True) -> Path:
    """URDF + YAML (+ STL) of the test robot in folder; returns the YAML path. limits: the hip
    joints' URDF range, rad (None: continuous joints); base_mesh False leaves base_link with
    no mesh (the YAML's surface_points mark the body)."""
    folder.mkdir(parents=True, exist_ok=True)
    write_stl(folder / 'leg.stl', c_leg(**LEG), units='m', ascii=True, name='leg')
    lx, ly, lz = BODY
    write_stl(folder / 'body.stl', box(lx, ly, lz, subdivisions=6)
              .transformed(_eye(), (0.5 * lx, 0.0, 0.5 * lz)), units='m', ascii=True,
              name='body')
    joint = ('<joint name="{n}_hip" type="{kind}"><parent link="base_link"/>'
             '<child link="{n}_leg"/><origin xyz="{x} {y} -0.004" rpy="0 0 0"/>'
             '<axis xyz="0 -1 0"/>{limit}</joint>')
    kind = 'continuous' if limits is None else 'revolute'
    limit = '' if limits is None else (f'<limit lower="{limits[0]}" upper="{limits[1]}" '
                                       'effort="1" velocity="10"/>')
    legs = []
    for n, x, side in (('lr', 0.025, 1), ('lf', 0.095, 1), ('rr', 0.025, -1),
                       ('rf', 0.095, -1)):
        scale = '-1 1 1' if side > 0 else '-1 -1 1'
        legs.append(f'<link name="{n}_leg"><collision><geometry><mesh filename="leg.stl" '
                    f'scale="{scale}"/></geometry></collision></link>')
        legs.append(joint.format(n=n, kind=kind, x=x, y=side * leg_y, limit=limit))
    base_geo = ('<collision><geometry><mesh filename="body.stl"/></geometry></collision>'
                if base_mesh else '')
    urdf = f'''<?xml version="1.0"?>
<robot name="boxbot">
  <link name="base_link">{base_geo}<inertial><origin xyz="0.06 0 0.006"/><mass value="0.2"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="2.4e-4" iyz="0" izz="1e-4"/></inertial></link>
  {"".join(legs)}
  <link name="winch_link"/>
  <joint name="winch_joint" type="fixed"><parent link="base_link"/><child link="winch_link"/>
    <origin xyz="0 0 0" rpy="0 0 0"/></joint>
</robot>
'''
    (folder / 'boxbot.urdf').write_text(urdf)
    (folder / 'boxbot.yaml').write_text(f'''name: boxbot
urdf: boxbot.urdf
tether_link: winch_link
char_length_m: 0.08
medium: m90_sand
base_pose: {{height: h, pitch: theta_b}}
surface_points: [[0.0, 0.0, 0.0], [{lx}, 0.0, 0.0]]
state:
  - {{name: h, unit: m, physical: [-0.05, 0.5]}}
  - {{name: theta_b, unit: deg, physical: [-90, 90]}}
  - {{name: theta_rear, unit: deg, joints: [lr_hip, rr_hip], physical: [-180, 180]}}
  - {{name: theta_front, unit: deg, joints: [lf_hip, rf_hip], physical: [-180, 180]}}
''')
    return folder / 'boxbot.yaml'


def _eye():
    import numpy as np
    return np.eye(3)
