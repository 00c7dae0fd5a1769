"""Anchor descriptions: a URDF (links, meshes, joints, inertials) plus a small YAML (what URDF
has no place for: the tether link, which joints are state variables, their units and ranges,
the base pose, the C-leg orientation of a pull, media defaults). docs/design/six-d.md,
"Anchor descriptions".

    description YAML + URDF --(state values)--> forward kinematics --> PosedAnchor (posed.py)

The URDF is read with the standard library's XML parser (URDF is plain XML); a file named
`*.xacro` is expanded first with the `xacro` package, as ROS's own tools do. Frames: base_link
is placed in the world from the state (its origin at height `base_pose.height`, turned by
rot_y(-pitch), as the robots' body frame B); every joint is origin (xyz, fixed-axis rpy) then
rotation about its axis by the joint value; the tether point is the origin of `tether_link`.
Mesh scales in the URDF are applied in the link frame; a negative determinant (a mirrored leg)
reverses the winding so normals stay outward.

The shipped descriptions (rftgls_core/data/<robot>.urdf and .yaml, leg mesh c_leg.stl) are
written by `description_writer.write_robot_description` from robots/presets.py, so `--anchor`
and `--robot` give the same numbers (tests/core/test_description.py). Mesh file names may be
relative to the URDF, `file://` paths or `package://PKG/...` URIs (resolved through
AMENT_PREFIX_PATH, as ROS tools do, without importing ROS).
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rftgls_conventions.safe_read import load_yaml, parse_yaml, read_bytes

from . import description_input as source
from .geometry.mesh import Facets, TriMesh
from .geometry.stl import MeshError, read_stl
from .geometry.transforms import parse_vector, rot_y, rpy_matrix
from .posed import PosedAnchor
from .quantities import MASS_KG, MESH_SCALE, POSITION_M
from .types import AnchorState, Pull

DATA = Path(__file__).resolve().parent / 'data'


class DescriptionError(ValueError):
    """A description that cannot be used (one line, names the file)."""


def _floats(text: str | None, default: tuple[float, ...], what: str) -> np.ndarray:
    return parse_vector(text, default, what, DescriptionError)


@dataclass(frozen=True)
class Link:
    name: str
    mesh: TriMesh | None            # in the link frame, m (origin and scale applied)
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray              # (4, 4)
    axis: np.ndarray


def _transform(origin) -> np.ndarray:
    t = np.eye(4)
    if origin is not None:
        t[:3, :3] = rpy_matrix(*_floats(origin.get('rpy'), (0, 0, 0), 'origin rpy'))
        t[:3, 3] = _floats(origin.get('xyz'), (0, 0, 0), 'origin xyz')
    return t


def urdf_bytes(path: str | Path, roots: tuple[Path, ...] | None = None) -> bytes:
    """The URDF XML of `path`, a `*.xacro` expanded in the sandbox, every file inside the
    allow-list `roots` (description_input.py; default: the file's folder and the installed
    packages). DescriptionError (one line) otherwise."""
    try:
        return source.urdf_bytes(path, roots)
    except source.SourceError as exc:
        raise DescriptionError(str(exc)) from None


def read_urdf(path: str | Path, roots: tuple[Path, ...] | None = None
              ) -> tuple[dict[str, Link], list[Joint]]:
    """Links (meshes loaded, in URDF order) and joints of a URDF file (or a `*.xacro` file,
    expanded first); files only inside the allow-list `roots` (urdf_bytes)."""
    path = Path(path)
    roots = source.allowed_roots(path.parent) if roots is None else roots
    try:
        root = ET.fromstring(urdf_bytes(path, roots))
    except ET.ParseError as exc:
        raise DescriptionError(f'{path}: cannot read URDF ({exc})') from None
    if root.tag != 'robot':
        raise DescriptionError(f'{path}: not a URDF (root element {root.tag!r})')
    links: dict[str, Link] = {}
    for el in root.findall('link'):
        name = el.get('name') or ''
        mesh = None
        geo = el.find('collision/geometry/mesh')
        if geo is None:
            geo = el.find('visual/geometry/mesh')
        if geo is not None:
            coll = el.find('collision') if el.find('collision/geometry/mesh') is not None \
                else el.find('visual')
            t = _transform(coll.find('origin') if coll is not None else None)
            _in_range(path, POSITION_M, t[:3, 3], f'link {name} origin xyz')
            try:
                m = read_stl(source.mesh_path(geo.get('filename') or '', path, roots), units='m')
            except (MeshError, OSError, source.SourceError) as exc:
                raise DescriptionError(f'{path}: link {name!r}: {exc}') from None
            scale = _floats(geo.get('scale'), (1, 1, 1), f'link {name} mesh scale')
            _in_range(path, MESH_SCALE, np.abs(scale), f'link {name} mesh scale')
            m = TriMesh(m.vertices * scale, m.faces if np.prod(scale) > 0 else m.faces[:, ::-1])
            mesh = m.transformed(t[:3, :3], t[:3, 3])
        mass, com = 0.0, np.zeros(3)
        inertial = el.find('inertial')
        if inertial is not None:
            mel = inertial.find('mass')
            mass = float(_floats(mel.get('value') if mel is not None else None, (0.0,),
                                 f'link {name} mass')[0])
            com = _transform(inertial.find('origin'))[:3, 3]
            _in_range(path, MASS_KG, [mass], f'link {name} mass')
            _in_range(path, POSITION_M, com, f'link {name} inertial origin')
        links[name] = Link(name, mesh, mass, com)
    joints = []
    for el in root.findall('joint'):
        parent, child = el.find('parent'), el.find('child')
        if parent is None or child is None:
            raise DescriptionError(f'{path}: joint {el.get("name")!r} lacks parent or child')
        axis_el = el.find('axis')
        ax = _floats(axis_el.get('xyz') if axis_el is not None else None, (1, 0, 0),
                     f'joint {el.get("name")} axis')
        if not np.linalg.norm(ax) > 1e-9:
            raise DescriptionError(f'{path}: joint {el.get("name")!r} axis has no direction')
        origin = _transform(el.find('origin'))
        _in_range(path, POSITION_M, origin[:3, 3], f'joint {el.get("name")} origin xyz')
        joints.append(Joint(el.get('name') or '', el.get('type') or 'fixed',
                            parent.get('link') or '', child.get('link') or '',
                            origin, ax / np.linalg.norm(ax)))
    return links, joints


def _in_range(path: Path, quantity, values, what: str) -> None:
    source.check_range(path, quantity, values, what, DescriptionError)


def _axis_rotation(axis: np.ndarray, q: float) -> np.ndarray:
    a = axis
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(q) * k + (1 - math.cos(q)) * (k @ k)


@dataclass(frozen=True)
class StateVariable:
    name: str
    unit: str                                   # 'm' or 'deg' (the YAML's; SI inside)
    joints: tuple[str, ...]
    physical: tuple[float, float]               # SI
    map_range: tuple[float, float, int] | None  # SI start, stop, count

    def to_si(self, value: float) -> float:
        return math.radians(value) if self.unit == 'deg' else float(value)


@dataclass(frozen=True)
class AnchorDescription:
    """A loaded description: URDF links and joints plus the YAML's extra facts (SI)."""

    name: str
    source: Path
    links: dict[str, Link]
    joints: list[Joint]
    tether_link: str
    char_length: float
    medium: str
    height_var: str
    pitch_var: str
    state: tuple[StateVariable, ...]
    pull_scale: dict[str, np.ndarray]
    pull_links: tuple[str, ...]
    symmetry: str = ''             # '' or 'sagittal': a claim, checked per pose, never trusted
    sha256: str = ''               # identity: description_sha256 of the files it was read from
    # Points of base_link (m, (K, 3)) whose reaching the free surface ends a slip simulation
    # (the robots' body plate ends); empty: the tether point (a buried body's own rule).
    surface_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    urdf_path: Path | None = None  # the URDF file it was read from

    def urdf_text(self) -> str:
        """The URDF as read, xacro expanded (what a ROS `robot_description` carries); '' when
        unknown."""
        if self.urdf_path is None:
            return ''
        return urdf_bytes(self.urdf_path, source.allowed_roots(self.source.parent)).decode()

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.state)

    def violations(self, values: dict[str, float]) -> list[str]:
        out = []
        for v in self.state:
            lo, hi = v.physical
            if not lo <= values[v.name] <= hi:
                f = 180.0 / math.pi if v.unit == 'deg' else 1.0
                out.append(f'{v.name} {values[v.name] * f:.6g} {v.unit} outside '
                           f'{lo * f:.6g}..{hi * f:.6g} {v.unit}')
        return out

    def base_pose(self, values: dict[str, float]) -> np.ndarray:
        """(4, 4) pose of base_link in the world for state values (SI, by name)."""
        base = np.eye(4)
        base[:3, :3] = rot_y(-values[self.pitch_var]) if self.pitch_var else np.eye(3)
        base[2, 3] = values[self.height_var] if self.height_var else 0.0
        return base

    def surface_min_z(self, values: dict[str, float]) -> float:
        """Height (m, world z; the free surface is 0) of the lowest `surface_points` point
        at state values, or of the tether point when the YAML names none: a slip
        simulation stops when it reaches 0, as the robots' `plate_min_z` does."""
        if len(self.surface_points):
            base = self.base_pose(values)
            return float(np.min(self.surface_points @ base[:3, :3].T[:, 2] + base[2, 3]))
        return float(self.pose(values).ref[2])

    def link_poses(self, values: dict[str, float],
                   joints: dict[str, float] | None = None) -> dict[str, np.ndarray]:
        """(4, 4) world pose of every link for state values (SI, by name): base_link from
        base_pose, each joint origin then rotation about its axis (translation along it for
        prismatic) by its value. The state variables drive their joints; `joints` (joint name
        -> rad or m) sets joints one by one on top (e.g. four measured leg angles)."""
        q: dict[str, float] = {}
        for v in self.state:
            for j in v.joints:
                q[j] = values[v.name]
        q.update(joints or {})
        world = {'base_link': self.base_pose(values)}
        pending = list(self.joints)
        while pending:
            progressed = False
            for jt in list(pending):
                if jt.parent in world:
                    t = world[jt.parent] @ jt.origin
                    if jt.kind in ('revolute', 'continuous'):
                        r = np.eye(4)
                        r[:3, :3] = _axis_rotation(jt.axis, q.get(jt.name, 0.0))
                        t = t @ r
                    elif jt.kind == 'prismatic':
                        r = np.eye(4)
                        r[:3, 3] = jt.axis * q.get(jt.name, 0.0)
                        t = t @ r
                    world[jt.child] = t
                    pending.remove(jt)
                    progressed = True
            if not progressed:
                raise ValueError(f'{self.source}: joints not connected to base_link: '
                                 f'{", ".join(j.name for j in pending)}')
        return world

    def pose(self, values: dict[str, float], pull: Pull | str = Pull.BACKWARD) -> PosedAnchor:
        """The posed description for state values (SI, by name) and a pull orientation."""
        missing = [n for n in self.state_names if n not in values]
        if missing:
            raise ValueError(f'{self.source}: state variables without a value: '
                             f'{", ".join(missing)}')
        pull = Pull(pull)
        world = self.link_poses(values)
        parts, mass, moment = [], 0.0, np.zeros(3)
        scale = self.pull_scale.get(pull.value, np.ones(3))
        for link in self.links.values():
            t = world[link.name]
            if link.mesh is not None:
                m = link.mesh
                if link.name in self.pull_links and not np.all(scale == 1.0):
                    m = TriMesh(m.vertices * scale,
                                m.faces if np.prod(scale) > 0 else m.faces[:, ::-1])
                parts.append(m.transformed(t[:3, :3], t[:3, 3]).facets())
            mass += link.mass
            moment += link.mass * (t[:3, :3] @ link.com + t[:3, 3])
        ref = world[self.tether_link][:3, 3].copy()
        com = moment / mass if mass > 0 else ref
        return PosedAnchor(name=self.name, facets=Facets.concatenate(parts), ref=ref, mass=mass,
                           com=com, char_length=self.char_length)


def load_description(path: str | Path) -> AnchorDescription:
    """Read a description YAML (and the URDF it names); DescriptionError on bad input."""
    path = Path(path)
    roots = source.allowed_roots(path.parent)
    try:
        doc = source.check_document(path, load_yaml(path, 'description', 'description'))
    except ValueError as exc:   # safe_read.InputFileError, source.SourceError
        raise DescriptionError(str(exc)) from None
    urdf_path = path.parent / str(doc['urdf'])
    links, joints = read_urdf(urdf_path, roots)
    tether = str(doc.get('tether_link', 'winch_link'))
    if tether not in links or 'base_link' not in links:
        raise DescriptionError(f'{path}: the URDF needs base_link and the tether link '
                               f'{tether!r}')
    state = []
    for item in doc.get('state') or []:
        name = str(item.get('name', ''))
        unit = str(item.get('unit', ''))
        if unit not in ('m', 'deg'):
            raise DescriptionError(f'{path}: state variable {name!r}: unit must be m or deg')
        f = math.radians(1.0) if unit == 'deg' else 1.0
        phys = item.get('physical')
        if not (isinstance(phys, list) and len(phys) == 2):
            raise DescriptionError(f'{path}: state variable {name!r} has no physical range '
                                   '[low, high]')
        mr = item.get('map')
        map_range = None
        if mr is not None:
            if not (isinstance(mr, list) and len(mr) == 3 and int(mr[2]) >= 2):
                raise DescriptionError(f'{path}: state variable {name!r}: map range must be '
                                       '[start, stop, count >= 2]')
            map_range = (float(mr[0]) * f, float(mr[1]) * f, int(mr[2]))
        js = tuple(str(j) for j in item.get('joints') or [])
        unknown = [j for j in js if j not in {jj.name for jj in joints}]
        if unknown:
            raise DescriptionError(f'{path}: state variable {name!r} drives unknown joints '
                                   f'{", ".join(unknown)}')
        state.append(StateVariable(name, unit, js, (float(phys[0]) * f, float(phys[1]) * f),
                                   map_range))
    if not state:
        raise DescriptionError(f'{path}: no state variables (`state:`)')
    bp = doc.get('base_pose') or {}
    names = {v.name for v in state}
    for key in ('height', 'pitch'):
        if bp.get(key) is not None and bp[key] not in names:
            raise DescriptionError(f'{path}: base_pose.{key} names no state variable')
    ps = doc.get('pull_scale') or {}
    sp = doc.get('surface_points') or []
    try:
        surface = np.asarray(sp, dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        surface = np.full((1, 3), np.nan)
    if not np.all(np.isfinite(surface)):
        raise DescriptionError(f'{path}: surface_points must be a list of [x, y, z] points of '
                               'base_link, m')
    return AnchorDescription(
        name=str(doc.get('name', path.stem)), source=path, links=links, joints=joints,
        tether_link=tether, char_length=float(doc.get('char_length_m', 0.1)),
        medium=str(doc.get('medium', 'glass_beads')), height_var=str(bp.get('height') or ''),
        pitch_var=str(bp.get('pitch') or ''), state=tuple(state),
        pull_scale={k: np.asarray(v, dtype=float) for k, v in ps.items() if k != 'links'},
        pull_links=tuple(ps.get('links') or ()), symmetry=_symmetry(path, doc),
        sha256=description_sha256(path), surface_points=surface, urdf_path=urdf_path)


def description_sha256(path: str | Path) -> str:
    """Identity of a description: hex SHA-256 over the bytes of its YAML, its URDF and every
    mesh file the URDF names (in the URDF's order; file names left out, so a copy of the same
    files elsewhere has the same identity). A map records it and answers only for it."""
    import hashlib

    path = Path(path)
    roots = source.allowed_roots(path.parent)
    h = hashlib.sha256(b'rftgls.anchor_description/1\0')

    def feed(data: bytes) -> None:
        h.update(len(data).to_bytes(8, 'little') + data)
    try:
        text = read_bytes(path, 'description', 'description')
        feed(text)
        doc = source.check_document(path, parse_yaml(text, path))
        urdf = path.parent / str(doc['urdf'])
        xml = urdf_bytes(urdf, roots)
        feed(xml)
        root = ET.fromstring(xml)
        seen: list[Path] = []
        for el in root.iter('mesh'):
            file = source.mesh_path(el.get('filename') or '', urdf, roots)
            if file not in seen:
                seen.append(file)
                feed(read_bytes(file, 'mesh', 'mesh'))
    except (ValueError, ET.ParseError) as exc:   # DescriptionError, safe_read, SourceError
        raise DescriptionError(f'{path}: cannot hash the description ({exc})') from None
    return h.hexdigest()


def map_axes(desc: AnchorDescription) -> dict[str, np.ndarray]:
    """The default map axes of a description: state name -> nodes (SI), from each variable's
    `map: [start, stop, count]`; DescriptionError naming the variables without one."""
    missing = [v.name for v in desc.state if v.map_range is None]
    if missing:
        raise DescriptionError(f'{desc.source}: state variable(s) {", ".join(missing)} have no '
                               'map range (`map: [start, stop, count]`); give one in the YAML '
                               'or on the command line')
    out = {}
    for v in desc.state:
        assert v.map_range is not None
        lo, hi, n = v.map_range
        out[v.name] = np.linspace(lo, hi, n)
    return out


def _symmetry(path: Path, doc: dict) -> str:
    claim = str(doc.get('symmetry') or '')
    if claim not in ('', 'sagittal'):
        raise DescriptionError(f'{path}: symmetry must be sagittal or absent, got {claim!r}')
    return claim


def shipped_description(robot: str) -> Path:
    """The shipped description YAML of a robot preset ('prototype', 'minirquad')."""
    return DATA / f'{robot}.yaml'


def state_values(state: AnchorState) -> dict[str, float]:
    """A robot AnchorState as the shipped descriptions' state variables (SI)."""
    return {'h': state.h, 'theta_b': state.theta_b, 'theta_l1': state.theta_l1,
            'theta_l2': state.theta_l2}


ROBOT_STATE = ('h', 'theta_b', 'theta_l1', 'theta_l2')


def robot_state_map(desc: AnchorDescription, mapping=None) -> dict[str, str]:
    """Which AnchorState quantity (ROBOT_STATE) feeds each state variable of desc, for the
    consumers that estimate a robot's AnchorState (capacity_node, the simulator ground, the
    lab tools): `mapping` (description variable -> quantity), default the variables' own
    names. Every variable needs one quantity, no quantity feeds two; unused quantities are
    left out (their inputs are still measured). DescriptionError (one line) otherwise.
    The user vouches for the meaning: h is the height of the tether point p above the
    surface, theta_b the body pitch (rot_y(-theta_b)), theta_l1/l2 the leg angles."""
    mapping = dict(mapping or {n: n for n in desc.state_names})
    need = f'the AnchorState quantities are {", ".join(ROBOT_STATE)}'
    unknown = sorted(set(mapping) - set(desc.state_names))
    if unknown:
        raise DescriptionError(f'{desc.source}: no state variable {", ".join(unknown)} (it '
                               f'declares {", ".join(desc.state_names)})')
    unfed = [n for n in desc.state_names if n not in mapping]
    bad = sorted({q for q in mapping.values() if q not in ROBOT_STATE})
    if unfed or bad:
        what = (f'state variable(s) {", ".join(unfed)} have no quantity' if unfed else
                f'not a quantity: {", ".join(bad)}')
        raise DescriptionError(f'{desc.source}: declares {", ".join(desc.state_names)}; {need} '
                               f'and each variable needs one ({what})')
    twice = sorted({q for q in mapping.values() if list(mapping.values()).count(q) > 1})
    if twice:
        raise DescriptionError(f'{desc.source}: {", ".join(twice)} feeds two state variables')
    return mapping


def parse_state_map(text: str) -> dict[str, str] | None:
    """'NAME=QUANTITY,...' (capacity_node's anchor_state_variables, the lab tools'
    --anchor-state) -> {NAME: QUANTITY}; '' -> None (the variables' own names).
    DescriptionError (one line) on an entry that is not NAME=QUANTITY with QUANTITY in
    ROBOT_STATE, or a NAME given twice."""
    if not text.strip():
        return None
    out: dict[str, str] = {}
    for item in text.split(','):
        name, sep, q = (x.strip() for x in item.partition('='))
        if not sep or not name or q not in ROBOT_STATE or name in out:
            raise DescriptionError(f'want NAME=ESTIMATE,... with ESTIMATE one of '
                                   f'{", ".join(ROBOT_STATE)} and each NAME once, got '
                                   f'{item.strip()!r}')
        out[name] = q
    return out
