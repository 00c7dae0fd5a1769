"""A legged robot as the quasi-static simulation sees it: a free base in the sagittal plane
and legs hinged to it, each leg a rigid RFT body turned by its servo.

Frames (docs/design/architecture.md): world W, z up, free surface z = 0. The base frame is the
robots' body frame B for the presets (origin at the winch point p) and URDF's base_link for a
description. Its pose is planar: origin at (x, 0, z) in the world, turned by rot_y(-theta_b),
so theta_b > 0 lifts the +x_B end. Each leg turns about an axis parallel to y_B through its
hip; its joint value q is the URDF joint value (for the presets, the paper's leg angle: the
axis is -y_B and q > 0 swings the toe toward +x_B).

Planar twists and wrenches are taken at the tether point p (world axes): twist (vx, vz, wy),
wrench (Fx, Fz, My), as everywhere in the stack. A leg turning at rate qdot about a hip at
a (world, relative to p) adds the planar twist qdot * J with J = s (-a_z, a_x, 1), s = +1 for
an axis along +y and -1 along -y (the rotation (dz, -dx) of a point about the hip).

Out-of-plane forces and moments (a left leg out of step with the right one while walking) are
dropped: the base keeps roll and yaw at zero. That is the sagittal model's assumption.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from rftgls_conventions import G  # m/s^2

from ..geometry.mesh import Facets, TriMesh
from ..geometry.shapes import box
from ..geometry.transforms import rot_y

# A joint whose limits span a full turn (within this, rad) turns freely: walking legs do.
FULL_TURN_TOL = 1e-6
_EYE3 = np.eye(3)       # read only: Leg.rotation adds to it at every pose of every leg


@dataclass(frozen=True)
class Leg:
    """One leg on one hip joint; SI, base frame B.

    facets: the leg's facets in its joint frame at q = 0 (m). hip: the joint frame origin in
    B (m). frame: rotation of the joint frame in B. axis: unit joint axis in the joint frame.
    dof: index of the commanded degree of freedom (state variable) that drives it.
    limits: (lower, upper) joint range, rad, or None for a leg that turns fully.
    twin: index of its mirror image about y_B = 0 (same hip x and z, mirrored mesh), or None.
    """

    name: str
    facets: Facets
    hip: np.ndarray
    frame: np.ndarray
    axis: np.ndarray
    dof: int
    limits: tuple[float, float] | None = None
    twin: int | None = None
    mesh: TriMesh | None = None        # joint frame, for drawings and the body check

    @cached_property
    def axis_base(self) -> np.ndarray:
        return self.frame @ self.axis

    @cached_property
    def sign(self) -> float:
        """+1 when the axis points along +y_B, -1 along -y_B."""
        return float(np.sign(self.axis_base[1]))

    @cached_property
    def _cross(self) -> tuple[np.ndarray, np.ndarray]:
        """The axis' cross-product matrix K and K @ K (Rodrigues' formula), computed once:
        the simulation poses every leg at every step."""
        a = self.axis
        k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        return k, k @ k

    def rotation(self, q: float) -> np.ndarray:
        """Rotation of the leg in B at joint value q (rad)."""
        k, kk = self._cross
        r = _EYE3 + math.sin(q) * k + (1.0 - math.cos(q)) * kk
        return self.frame @ r


@dataclass(frozen=True)
class BasePose:
    """Planar pose of the base frame: origin (x, z) in the world, m; pitch theta_b, rad."""

    x: float
    z: float
    theta_b: float

    @property
    def rotation(self) -> np.ndarray:
        return rot_y(-self.theta_b)

    @property
    def origin(self) -> np.ndarray:
        return np.array([self.x, 0.0, self.z])

    def moved(self, twist: np.ndarray, ref: np.ndarray, dt: float) -> 'BasePose':
        """The pose after the planar twist (vx, vz, wy) at the world point ref for dt (s):
        ref moves by (vx, vz) dt and the base turns about it by -wy dt (wy about +y tilts
        x_B down)."""
        vx, vz, wy = (float(v) for v in twist)
        dth = -wy * dt
        c, s = math.cos(dth), math.sin(dth)
        ox, oz = self.x - ref[0], self.z - ref[2]
        # rot_y(-dth) in the x-z plane: (x, z) -> (c x - s z, s x + c z)
        nx, nz = c * ox - s * oz, s * ox + c * oz
        return BasePose(ref[0] + vx * dt + nx, ref[2] + vz * dt + nz, self.theta_b + dth)


@dataclass(frozen=True)
class Multibody:
    """A free base and its legs (SI). base: the base's facets in B, or None when the robot
    has no base mesh (then `surface_points` of B mark where it would meet the sand).
    mass (kg) and com (B, m): the whole robot's (legs are massless in the model; their
    weight is in mass). tether: the tether point p in B, m. dof_names: the commanded degrees
    of freedom in order (the presets: theta_l1, theta_l2). char_length: L_c of the scaled
    metric, m. leg_order names which leg is LH, LF, RH, RF for the walking gaits.
    inertia: the robot's moment of inertia about y through its centre of mass, kg m^2 (it only
    matters where the robot falls, balance.py).
    """

    name: str
    base: Facets | None
    base_mesh: TriMesh | None
    legs: tuple[Leg, ...]
    mass: float
    com: np.ndarray
    tether: np.ndarray
    dof_names: tuple[str, ...]
    char_length: float
    surface_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    leg_order: dict = field(default_factory=dict)
    inertia: float = 0.0
    notes: dict = field(default_factory=dict, compare=False)

    @property
    def weight(self) -> float:
        return self.mass * G

    def joint_values(self, dof_values) -> np.ndarray:
        """Leg joint values (n_legs,) from one value per degree of freedom."""
        v = np.asarray(dof_values, dtype=float)
        return np.array([v[leg.dof] for leg in self.legs])

    def describe(self) -> dict:
        return {'name': self.name, 'mass_kg': self.mass, 'com_m': self.com.tolist(),
                'tether_m': self.tether.tolist(), 'dofs': list(self.dof_names),
                'legs': [leg.name for leg in self.legs],
                'base_facets': 0 if self.base is None else len(self.base),
                'leg_facets': [len(leg.facets) for leg in self.legs], 'notes': dict(self.notes)}

    def pose(self, base: BasePose, q: np.ndarray) -> 'PosedMultibody':
        """World facets, hip Jacobians and gravity at a base pose and leg joint values (rad)."""
        rb = base.rotation
        o = base.origin
        p = o + rb @ self.tether
        legs, jac, hips = [], np.zeros((len(self.legs), 3)), np.zeros((len(self.legs), 3))
        for i, leg in enumerate(self.legs):
            hip = o + rb @ leg.hip
            legs.append(leg.facets.transformed(rb @ leg.rotation(float(q[i])), hip))
            a = hip - p
            jac[i] = leg.sign * np.array([-a[2], a[0], 1.0])
            hips[i] = hip
        base_f = None if self.base is None else self.base.transformed(rb, o)
        com = o + rb @ self.com
        w = self.weight
        gravity = np.array([0.0, -w, w * (com[0] - p[0])])
        low = (float(np.min((self.surface_points @ rb.T)[:, 2] + o[2]))
               if len(self.surface_points) else math.inf)
        return PosedMultibody(self, base, np.asarray(q, dtype=float).copy(), p, legs, base_f,
                              jac, hips, gravity, com, low)

    def leg_points_in_base(self, i: int, q: float) -> np.ndarray:
        """Vertices (or facet centroids) of leg i in B at joint value q, m."""
        leg = self.legs[i]
        pts = leg.mesh.vertices if leg.mesh is not None else leg.facets.centroids
        return pts @ leg.rotation(q).T + leg.hip


@dataclass(frozen=True)
class PosedMultibody:
    """A robot placed in the world. legs: world facets per leg; base: world facets of the base
    (or None); jac: (n_legs, 3) planar twist at p per unit joint rate; hips: (n_legs, 3)
    world hip points; gravity: planar gravity wrench about p (N, N m); com: world centre of
    mass; surface_min_z: lowest `surface_points` point (inf when none)."""

    robot: Multibody
    base_pose: BasePose
    q: np.ndarray
    ref: np.ndarray
    legs: list[Facets]
    base: Facets | None
    jac: np.ndarray
    hips: np.ndarray
    gravity: np.ndarray
    com: np.ndarray
    surface_min_z: float

    @cached_property
    def leg_low(self) -> np.ndarray:
        """Each leg's lowest facet centroid, m (world; inf for a leg without facets): whether
        it touches the sand, asked several times per step."""
        return np.array([f.centroids[:, 2].min() if len(f) else math.inf for f in self.legs])

    @cached_property
    def base_low(self) -> float:
        """The base's lowest facet centroid, m (world; inf without a base mesh)."""
        if self.base is None or not len(self.base):
            return math.inf
        return float(self.base.centroids[:, 2].min())

    def buried_counts(self) -> tuple[int, list[int]]:
        """Buried facets of the base and of each leg."""
        b = 0 if self.base is None else int(np.count_nonzero(self.base.centroids[:, 2] < 0.0))
        return b, [int(np.count_nonzero(f.centroids[:, 2] < 0.0)) for f in self.legs]

    def lowest_z(self) -> float:
        """Lowest facet centroid of the whole robot, m (world)."""
        return float(min(self.leg_low.min(initial=math.inf), self.base_low))


# ------------------------------------------------------------------------------ the presets
def from_preset(robot, pull='backward') -> Multibody:
    """The multibody form of a robots/ preset (RobotModel): four legs (left and right on the
    proximal and distal axles, each its own servo), the base plate as a box from
    robots/presets.py (its width and thickness are assumptions there). pull: the C-legs'
    orientation (types.Pull); MiniRQuad walks and tugs with the backward one (the winch sits
    on its back, paper sec. VI-A)."""
    from ..robots.presets import PLATE_THICKNESS, PLATE_WIDTH
    from ..types import Pull
    pull = Pull(pull)
    left = robot._leg_facets(pull)
    mesh = robot.leg_mesh
    if pull is Pull.BACKWARD:
        mesh = TriMesh(mesh.vertices * np.array([-1.0, 1.0, 1.0]), mesh.faces[:, ::-1])
    mirror = np.array([1.0, -1.0, 1.0])
    right = Facets(left.centroids * mirror, left.normals * mirror, left.areas)
    right_mesh = TriMesh(mesh.vertices * mirror, mesh.faces[:, ::-1])
    axis = np.array([0.0, -1.0, 0.0])
    legs = []
    names = ('left_proximal', 'left_distal', 'right_proximal', 'right_distal')
    for k, name in enumerate(names):
        axle = k % 2
        side = 1.0 if k < 2 else -1.0
        legs.append(Leg(f'{name}_hip', left if side > 0 else right,
                        np.array([robot.axle_x[axle], side * robot.leg_y[axle], robot.axle_z]),
                        np.eye(3), axis, dof=axle, limits=None, twin=(k + 2) % 4,
                        mesh=mesh if side > 0 else right_mesh))
    plate = box(robot.plate_length, PLATE_WIDTH, PLATE_THICKNESS, subdivisions=8)
    plate = plate.transformed(np.eye(3), np.array([0.5 * robot.plate_length, 0.0,
                                                   0.5 * PLATE_THICKNESS]))
    ends = np.array([[0.0, 0.0, 0.0], [robot.plate_length, 0.0, 0.0]])
    notes = dict(robot.notes)
    notes.update(plate_width_m='assumed', plate_thickness_m='assumed',
                 leg_mass='in the body (legs massless)',
                 inertia='assumed: the mass spread over the body plate, m (L^2 + t^2) / 12')
    return Multibody(
        name=robot.name, base=plate.facets(), base_mesh=plate, legs=tuple(legs),
        mass=robot.mass, com=np.array([robot.com[0], 0.0, robot.com[1]]),
        tether=np.zeros(3), dof_names=('theta_l1', 'theta_l2'), char_length=robot.char_length,
        surface_points=ends,
        leg_order={'LH': 0, 'LF': 1, 'RH': 2, 'RF': 3}, notes=notes,
        inertia=robot.mass * (robot.plate_length ** 2 + PLATE_THICKNESS ** 2) / 12.0)


def dof_range(robot: Multibody, dof: int) -> tuple[float, float] | None:
    """The joint range shared by every leg of a degree of freedom (rad), None if all turn
    fully."""
    lims = [leg.limits for leg in robot.legs if leg.dof == dof and leg.limits is not None]
    if not lims:
        return None
    return (max(lo for lo, _ in lims), min(hi for _, hi in lims))
