"""The two robots of the paper. Values the paper gives are cited; the rest are assumptions.

| quantity | prototype (sec. IV) | MiniRQuad (sec. VI) | source |
| mass | 0.120 kg | 0.296 kg | paper |
| proximal / distal axle from p | 0.050 / 0.120 m | 0.030 / 0.120 m | paper (prototype); MiniRQuad: 90 mm wheelbase from the paper, 30 mm offset assumed |
| C-leg | 90 mm arc diameter, 5 mm thick | same legs | paper |
| C-leg width | 10 mm | 10 mm | assumed |
| axle height above p | 10 mm | 10 mm | assumed |
| lateral leg offsets (proximal, distal) | 40, 55 mm | 45, 45+10 mm | assumed (staggered so distal legs are not shadowed) |
| centre of mass | midway between axles, at axle height | same | assumed |
| body plate width, thickness (the multibody simulation's base body) | 60, 10 mm | same | assumed |
"""
from __future__ import annotations

from functools import lru_cache

from ..geometry.shapes import c_leg
from .robot import Robot

LEG_ARC_DIAMETER = 0.090   # m, paper
LEG_THICKNESS = 0.005      # m, paper
LEG_WIDTH = 0.010          # m, assumed
LEG_ARC_SEGMENTS = 24      # default mesh resolution along the arc (see README speed/accuracy)
AXLE_HEIGHT = 0.010        # m above p along z_B, assumed
PLATE_WIDTH = 0.060        # m across y_B, assumed (legs outside it: |y| >= 40 mm)
PLATE_THICKNESS = 0.010    # m, z_B from 0 (p) up, assumed


def _leg(n_arc: int):
    return c_leg(arc_diameter=LEG_ARC_DIAMETER, thickness=LEG_THICKNESS, width=LEG_WIDTH,
                 n_arc=n_arc)


# What the two robots share and the paper does not give (see the table above).
_ASSUMED = {'leg_width_m': 'assumed', 'axle_z_m': 'assumed', 'leg_y_m': 'assumed',
            'com': 'assumed midway between axles', 'plate_length_m': 'assumed'}


def _robot(name: str, mass: float, axles: tuple[float, float], leg_y: tuple[float, float],
           plate_length: float, n_arc: int, notes: dict[str, str]) -> Robot:
    """A robot of the paper's layout: mass kg, axles x (m from p), the same C-legs at
    AXLE_HEIGHT, centre of mass midway between the axles, L_c = 0.1 m."""
    return Robot(
        name=name, mass=mass, com=(0.5 * sum(axles), AXLE_HEIGHT), axle_x=axles,
        axle_z=AXLE_HEIGHT, leg_y=leg_y, leg_mesh=_leg(n_arc), plate_length=plate_length,
        char_length=0.1, notes={**notes, **_ASSUMED})


@lru_cache(maxsize=16)
def prototype(n_arc: int = LEG_ARC_SEGMENTS) -> Robot:
    return _robot('prototype', 0.120, (0.050, 0.120), (0.040, 0.055), 0.140, n_arc, {})


@lru_cache(maxsize=16)
def minirquad(n_arc: int = LEG_ARC_SEGMENTS) -> Robot:
    return _robot('minirquad', 0.296, (0.030, 0.120), (0.045, 0.055), 0.150, n_arc,
                  {'proximal_axle_x_m': 'assumed (wheelbase 0.090 m from the paper)'})


ROBOTS = {'prototype': prototype, 'minirquad': minirquad}


def get_robot(name: str, n_arc: int = LEG_ARC_SEGMENTS) -> Robot:
    key = name.strip().lower()
    if key not in ROBOTS:
        raise ValueError(f'unknown robot {name!r}; known robots: {", ".join(sorted(ROBOTS))}')
    return ROBOTS[key](n_arc)
