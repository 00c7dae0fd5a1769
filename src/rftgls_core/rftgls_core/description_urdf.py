"""Reading a URDF (or xacro) file into links and joints, with their meshes loaded.

The URDF is read with the standard library's XML parser (URDF is plain XML); a file named
`*.xacro` is expanded first with the `xacro` package, as ROS's own tools do, inside the
sandbox of description_input.py (an allow-list of folders, no environment). Every joint is
origin (xyz, fixed-axis rpy) then rotation about its axis by the joint value. Mesh scales are
applied in the link frame; a negative determinant (a mirrored leg) reverses the winding so
normals stay outward. Mesh file names may be relative to the URDF, `file://` paths or
`package://PKG/...` URIs (resolved through AMENT_PREFIX_PATH, as ROS tools do, without
importing ROS). Masses, origins and mesh scales are checked against their physical ranges.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import description_input as source
from .geometry.mesh import TriMesh
from .geometry.stl import MeshError, read_stl
from .geometry.transforms import parse_vector, rpy_matrix
from .quantities import MASS_KG, MESH_SCALE, POSITION_M


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
