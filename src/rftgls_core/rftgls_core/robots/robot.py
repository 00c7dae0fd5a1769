"""Sagittal robots: legs on two axles posed from an anchor state
(h, thetaB, thetaL1, thetaL2).

Frames (docs/design/architecture.md). World W: z up, free surface z = 0. Body B: origin at the
winch point p, x_B along the body from p toward the axles, z_B up out of the body plate,
y_B = z_B x x_B. At thetaB = 0, B is aligned with W and p sits at (0, 0, h).

Legs: each axle carries a left and a right C-leg at y_B = +-lateral offset. A leg's own frame
has the hip (axle) at its origin, the axle along y and, at leg angle 0, the chord of the C
along -z_B. Positive leg angles swing the toe toward +x_B (away from p), so a larger thetaL1
puts the proximal contact further from p, as the paper states. The right leg is the exact
mirror image of the left one, which is what lets the engine halve the work.

Pull orientation: the paper flips the C-legs to test forward and backward pulls, and does not
draw which way the C opens. Assumption: in a forward pull the C bulges away from p (+x_B), in
a backward pull toward p (-x_B). This is the orientation whose capacity map reproduces the
paper's Fig. 9 trends: forward capacity saddle-shaped and rising for negative thetaL1 with
the weight barely held near (40, 40) deg; backward capacity rising with thetaL2 while thetaL1
matters little. The opposite choice swaps the two maps (checked, see README).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from rftgls_conventions import G  # m/s^2

from ..geometry.mesh import Facets, TriMesh
from ..geometry.transforms import rot_y
from ..types import AnchorState, Pull


@dataclass(frozen=True)
class StateRange:
    """The anchor states a robot can physically be in, SI (bounds inclusive).

    Beyond them a state is a typo, a unit slip (mm for m) or a broken sensor, not a pose, and
    no capacity is computed for it (OUT_OF_RANGE 'outside_physical_range'). Inside them a state
    may still hold nothing (no buried leg -> UNSUPPORTED): that is physics, not range.
    h: winch-point height above the free surface, m. p buried deeper than the body is tall is
        impossible; far above the sand the robot is carried, not anchored.
    theta_b: body pitch, rad (beyond +-90 deg the robot lies on its back).
    theta_leg: each leg angle, rad; the legs turn fully, so any pose is one value in
        [-pi, pi] (a CLI value beyond it must be wrapped first).
    """

    h: tuple[float, float] = (-0.05, 0.5)
    theta_b: tuple[float, float] = (-0.5 * math.pi, 0.5 * math.pi)
    theta_leg: tuple[float, float] = (-math.pi, math.pi)

    def violations(self, state: AnchorState) -> list[str]:
        """One text per coordinate outside the range (empty when the state is inside)."""
        out = []
        for name, value, (lo, hi), unit, f in (
                ('h', state.h, self.h, 'm', 1.0),
                ('theta_b', state.theta_b, self.theta_b, 'deg', 180.0 / math.pi),
                ('theta_l1', state.theta_l1, self.theta_leg, 'deg', 180.0 / math.pi),
                ('theta_l2', state.theta_l2, self.theta_leg, 'deg', 180.0 / math.pi)):
            if not lo <= value <= hi:
                out.append(f'{name} {value * f:.6g} {unit} outside {lo * f:.6g}..{hi * f:.6g} '
                           f'{unit}')
        return out


@dataclass(frozen=True)
class Robot:
    """Every dimension the RFT-GLS model needs; SI units, body frame B (see module doc).

    Numbers the paper does not give are assumptions, marked in the presets.
    """

    name: str
    mass: float                         # kg
    com: tuple[float, float]            # (x_B, z_B) of the centre of mass, m
    axle_x: tuple[float, float]         # proximal, distal axle distance from p along x_B, m
    axle_z: float                       # axle height above p along z_B, m
    leg_y: tuple[float, float]          # lateral offsets of proximal, distal legs (|y_B|), m
    leg_mesh: TriMesh                   # one C-leg in its own frame (bulge toward +x), m
    plate_length: float                 # body plate from x_B = 0 to plate_length, m
    char_length: float                  # lever arm that makes rotation comparable to translation, m
    notes: dict = field(default_factory=dict, compare=False)
    state_range: StateRange = field(default_factory=StateRange)

    def with_leg_mesh(self, mesh: TriMesh) -> 'Robot':
        """The same robot with another leg (e.g. an STL file), in the leg frame above."""
        return replace(self, leg_mesh=mesh)

    def describe(self) -> dict:
        return {'name': self.name, 'mass_kg': self.mass, 'com_m': list(self.com),
                'axle_x_m': list(self.axle_x), 'axle_z_m': self.axle_z, 'leg_y_m': list(self.leg_y),
                'leg_facets': int(len(self.leg_mesh.faces)), 'plate_length_m': self.plate_length,
                'char_length_m': self.char_length, 'assumptions': dict(self.notes)}

    def _leg_facets(self, pull: Pull) -> Facets:
        """The leg's facets in its own frame for this pull, computed once per leg mesh (a
        quarter of a pose's cost at the sensor rate); read-only, so the cache cannot drift."""
        cache: tuple[TriMesh, dict[Pull, Facets]] | None = self.__dict__.get('_leg_facets_cache')
        if cache is None or cache[0] is not self.leg_mesh:
            cache = (self.leg_mesh, {})
            object.__setattr__(self, '_leg_facets_cache', cache)
        if pull not in cache[1]:
            base = self.leg_mesh.facets()
            # The leg mesh bulges toward +x (forward pulls); mirror it for backward pulls.
            if pull is Pull.BACKWARD:  # reflected facets: normals reflect too, stay outward
                leg_flip = np.diag([-1.0, 1.0, 1.0])
                base = Facets(base.centroids @ leg_flip, base.normals @ leg_flip, base.areas)
            for a in (base.centroids, base.normals, base.areas):
                a.flags.writeable = False
            cache[1][pull] = base
        return cache[1][pull]

    def pose(self, state: AnchorState, pull: Pull | str = Pull.BACKWARD) -> 'PosedRobot':
        """World-frame facets of all four legs and the gravity wrench about p."""
        pull = Pull(pull)
        body_rot = rot_y(-state.theta_b)          # x_B tilts up for positive thetaB
        p = np.array([0.0, 0.0, state.h])
        base = self._leg_facets(pull)
        left = []
        for ax, ly, angle in zip(self.axle_x, self.leg_y, (state.theta_l1, state.theta_l2)):
            rot = body_rot @ rot_y(-angle)
            hip = p + body_rot @ np.array([ax, ly, self.axle_z])
            left.append(base.transformed(rot, hip))
        left_f = Facets.concatenate(left)
        mirror = np.array([1.0, -1.0, 1.0])
        right_f = Facets(left_f.centroids * mirror, left_f.normals * mirror, left_f.areas)
        facets = Facets.concatenate([left_f, right_f])
        com_w = body_rot @ np.array([self.com[0], 0.0, self.com[1]])
        weight = self.mass * G
        # Gravity (0, -mg) at the COM, moment about p: My = r_z Fx - r_x Fz = m g r_x.
        gravity = np.array([0.0, -weight, weight * com_w[0]])
        plate_end = p + body_rot @ np.array([self.plate_length, 0.0, 0.0])
        return PosedRobot(robot=self, state=state, pull=pull, facets=facets, ref=p,
                          gravity_wrench=gravity, plate_min_z=float(min(p[2], plate_end[2])))


@dataclass(frozen=True)
class PosedRobot:
    """A robot placed in the world: facets (world, m), reference point p, gravity wrench.

    gravity_wrench: planar (Fx, Fz, My) of gravity about p, N and N m.
    plate_min_z: lowest point of the body plate, m (the plate touches the sand at 0).
    The body is symmetric about the plane y = 0.
    """

    robot: Robot
    state: AnchorState
    pull: Pull
    facets: Facets
    ref: np.ndarray
    gravity_wrench: np.ndarray
    plate_min_z: float
    mirror_y: float = 0.0

    @property
    def buried_facets(self) -> int:
        return int(np.count_nonzero(self.facets.centroids[:, 2] < 0.0))
