"""The transform math of state_publisher, ROS-free: URDF joints, the transforms it publishes,
and a tiny TF tree resolver (used by the tests to check that every frame_id resolves).

What robot_state_publisher does, for the URDFs of this project (rftgls_core/data/*.urdf):

- every `fixed` joint is one static transform parent -> child (its origin), for /tf_static;
- every `revolute` / `continuous` joint is origin then a rotation by the joint value about
  its axis, and `prismatic` origin then a translation along it, for /tf;
- odom -> base_link places the body in the world (`odom_to_base`): base_link's origin is the
  winch point p at height h above the free surface (z of odom = 0 on the sand), turned by the
  body pitch theta_B (rftgls_conventions: nose up positive, a rotation of -theta_B about
  +y). x and y of p are NOT observed by the robot's sensors: they are 0 (the robot stands at
  the origin of odom); roll and yaw are not modelled (the planar model of the paper).
- odom -> anchor (`odom_to_anchor`): world-aligned axes at p, the frame of capacity_node's
  planar wrenches and twists (its `frame_id`, default 'anchor').

Transforms are (translation m, quaternion x, y, z, w) of the child frame in the parent frame,
as geometry_msgs/TransformStamped carries them.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from rftgls_conventions import pitch_to_quat_xyzw
from rftgls_core.geometry.transforms import matrix_to_quat, parse_vector, quat_to_matrix, rpy_matrix

MOVING = ('revolute', 'continuous', 'prismatic')
KINDS = MOVING + ('fixed', 'floating', 'planar')


class UrdfError(ValueError):
    """A URDF that cannot be used (one line)."""


@dataclass(frozen=True)
class Transform:
    """child's pose in parent: translation (m) and unit quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]

    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous matrix mapping child coordinates into parent coordinates."""
        t = np.eye(4)
        t[:3, :3] = quat_to_matrix(self.rotation)
        t[:3, 3] = self.translation
        return t


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray          # (4, 4), child-at-zero in parent
    axis: np.ndarray            # (3,) unit, in the joint frame


def _floats(text: str | None, default: tuple[float, ...], what: str) -> np.ndarray:
    return parse_vector(text, default, what, UrdfError)


def parse_urdf_joints(text: str) -> list[UrdfJoint]:
    """The joints of a URDF document (text). Meshes are not read: only the tree matters here.
    UrdfError on a document that is not a URDF, a joint without parent or child, an unknown
    joint type, a zero axis or non-finite numbers."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise UrdfError(f'robot_description is not XML ({exc})') from None
    if root.tag != 'robot':
        raise UrdfError(f'robot_description is not a URDF (root element {root.tag!r})')
    joints = []
    for el in root.findall('joint'):
        name = el.get('name') or ''
        parent, child = el.find('parent'), el.find('child')
        if parent is None or child is None or not parent.get('link') or not child.get('link'):
            raise UrdfError(f'joint {name!r} lacks a parent or child link')
        kind = el.get('type') or ''
        if kind not in KINDS:
            raise UrdfError(f'joint {name!r}: unknown type {kind!r}')
        o = el.find('origin')
        t = np.eye(4)
        if o is not None:
            t[:3, :3] = rpy_matrix(*_floats(o.get('rpy'), (0.0, 0.0, 0.0), f'joint {name} rpy'))
            t[:3, 3] = _floats(o.get('xyz'), (0.0, 0.0, 0.0), f'joint {name} xyz')
        a = el.find('axis')
        axis = _floats(a.get('xyz') if a is not None else None, (1.0, 0.0, 0.0),
                       f'joint {name} axis')
        n = float(np.linalg.norm(axis))
        if kind in MOVING and n < 1e-9:
            raise UrdfError(f'joint {name!r}: zero axis')
        joints.append(UrdfJoint(name, kind, parent.get('link') or '', child.get('link') or '',
                                t, axis / n if n > 0 else axis))
    children = [j.child for j in joints]
    dup = sorted({c for c in children if children.count(c) > 1})
    if dup:
        raise UrdfError(f'links with more than one parent joint: {", ".join(dup)}')
    return joints


def _transform(parent: str, child: str, m: np.ndarray) -> Transform:
    tx, ty, tz = (float(c) for c in m[:3, 3])
    return Transform(parent, child, (tx, ty, tz), matrix_to_quat(m[:3, :3]))


def joint_transform(joint: UrdfJoint, value: float = 0.0, prefix: str = '') -> Transform:
    """parent -> child of one joint at `value` (rad for revolute/continuous, m for prismatic;
    ignored for fixed joints). prefix: put in front of both frame names (tf frame_prefix)."""
    m = joint.origin.copy()
    if joint.kind in ('revolute', 'continuous'):
        a, s, c = joint.axis, math.sin(value), math.cos(value)
        k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        r = np.eye(4)
        r[:3, :3] = np.eye(3) + s * k + (1 - c) * (k @ k)     # Rodrigues
        m = m @ r
    elif joint.kind == 'prismatic':
        r = np.eye(4)
        r[:3, 3] = joint.axis * value
        m = m @ r
    return _transform(prefix + joint.parent, prefix + joint.child, m)


def static_transforms(joints: Iterable[UrdfJoint], prefix: str = '') -> list[Transform]:
    """The fixed joints' transforms (/tf_static)."""
    return [joint_transform(j, 0.0, prefix) for j in joints if j.kind == 'fixed']


def moving_transforms(joints: Iterable[UrdfJoint], names: Sequence[str],
                      positions: Sequence[float], prefix: str = '') -> list[Transform]:
    """/tf of a JointState (names, positions): one transform per moving URDF joint the message
    names (the URDF's joints carry the driver's JointState names, as robot_state_publisher
    requires); other names are ignored, and a name without a finite position gives no
    transform (never a made-up angle)."""
    by_name = {j.name: j for j in joints if j.kind in MOVING}
    out = []
    for name, pos in zip(names, positions, strict=False):
        j = by_name.get(name)
        if j is not None and math.isfinite(pos):
            out.append(joint_transform(j, float(pos), prefix))
    return out


def odom_to_base(h_m: float, theta_b_rad: float, odom: str = 'odom',
                 base: str = 'base_link') -> Transform:
    """The body in the world: base_link (origin at p) at height h_m above the free surface,
    pitched by theta_b_rad (nose up positive). x, y = 0: not observed (module doc)."""
    return Transform(odom, base, (0.0, 0.0, float(h_m)), pitch_to_quat_xyzw(theta_b_rad))


def odom_to_anchor(h_m: float, odom: str = 'odom', anchor: str = 'anchor') -> Transform:
    """World-aligned axes at p (capacity_node's output frame): odom translated to p."""
    return Transform(odom, anchor, (0.0, 0.0, float(h_m)), (0.0, 0.0, 0.0, 1.0))


# ----------------------------------------------------------------------------- resolver
class TfTree:
    """A tiny TF buffer without time: the latest transform per child frame (tf2's rule: one
    parent per frame). `root(frame)` walks parents to the top; `to_root(frame)` composes the
    transforms on the way (child coordinates -> root coordinates)."""

    def __init__(self, transforms: Iterable[Transform] = ()):
        self.edges: dict[str, Transform] = {}
        self.add(transforms)

    def add(self, transforms: Iterable[Transform]) -> None:
        for t in transforms:
            self.edges[t.child] = t

    @property
    def frames(self) -> set[str]:
        return set(self.edges) | {t.parent for t in self.edges.values()}

    def chain(self, frame: str) -> list[str]:
        """frame, its parent, ... up to the root. KeyError for a frame the tree does not
        know; ValueError on a loop."""
        if frame not in self.frames:
            raise KeyError(f'frame {frame!r} is not in the tree')
        out = [frame]
        while out[-1] in self.edges:
            nxt = self.edges[out[-1]].parent
            if nxt in out:
                raise ValueError(f'loop in the tree: {" -> ".join(out + [nxt])}')
            out.append(nxt)
        return out

    def root(self, frame: str) -> str:
        return self.chain(frame)[-1]

    def to_root(self, frame: str) -> np.ndarray:
        """(4, 4) matrix mapping `frame` coordinates into its root's coordinates."""
        m = np.eye(4)
        for f in self.chain(frame)[:-1]:
            m = self.edges[f].matrix() @ m
        return m

    def unresolved(self, frames: Iterable[str], root: str | None = None) -> dict[str, str]:
        """Frames that do not resolve (to `root`, or to one common root when None), with the
        reason; {} when all of them do."""
        bad: dict[str, str] = {}
        roots: dict[str, str] = {}
        for f in frames:
            try:
                roots[f] = self.root(f)
            except (KeyError, ValueError) as exc:
                bad[f] = str(exc.args[0])
        want = root if root is not None else (
            max(set(roots.values()), key=list(roots.values()).count) if roots else None)
        for f, r in roots.items():
            if r != want:
                bad[f] = f'resolves to {r!r}, not {want!r}'
        return bad


def tree_from(static: Iterable[Transform], dynamic: Iterable[Transform]) -> TfTree:
    """A TfTree of /tf_static and /tf transforms (dynamic ones win for the same child)."""
    tree = TfTree(static)
    tree.add(dynamic)
    return tree

