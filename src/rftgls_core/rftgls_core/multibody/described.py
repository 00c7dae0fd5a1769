"""A described robot (URDF + YAML, description.py) as a Multibody: base_link and its legs.

What the simulation needs beyond a posed anchor, and where it comes from:

- the base: base_link's mesh (collision, else visual), an RFT body like the legs. Without one
  the YAML's `surface_points` mark where the base is; a run stops (unsupported,
  base_in_sand) if they go below the sand, since nothing would resist them there;
- the legs: every link hinged to base_link by one revolute or continuous joint (links fixed
  to a leg go with it). Each joint's axis must be parallel to y of base_link: the simulation
  is sagittal (DescriptionError otherwise); a joint hinged to a leg is not simulated
  (DescriptionError: legs with knees are beyond this model);
- the degrees of freedom: the YAML's state variables that name joints, in YAML order (for the
  shipped robots theta_l1, theta_l2); each drives its joints with one value;
- joint ranges: URDF <limit lower upper> of revolute joints (a range of a full turn or more,
  and continuous joints, turn freely);
- mass, centre of mass and inertia about y through it: the URDF inertials of all links (the
  legs' included; the simulation puts it all on the base);
- the tether point: the origin of the YAML's tether_link; C-leg orientation: the YAML's
  pull_scale for the pull, as the posed anchors use it.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from ..description import AnchorDescription, DescriptionError, Joint
from ..geometry.mesh import TriMesh
from ..types import Pull
from .robot import FULL_TURN_TOL, Leg, Multibody


def _limits(desc: AnchorDescription) -> dict[str, tuple[float, float]]:
    """URDF <limit lower upper> per revolute joint, rad (absent: no limit read)."""
    if desc.urdf_path is None:
        return {}
    root = ET.fromstring(desc.urdf_text())
    out = {}
    for el in root.findall('joint'):
        lim = el.find('limit')
        lower = None if lim is None else lim.get('lower')
        upper = None if lim is None else lim.get('upper')
        if el.get('type') == 'revolute' and lower is not None and upper is not None:
            out[el.get('name') or ''] = (float(lower), float(upper))
    return out


def _inertia(desc: AnchorDescription) -> dict[str, float]:
    """iyy of each link's inertial (about its centre of mass), kg m^2."""
    if desc.urdf_path is None:
        return {}
    root = ET.fromstring(desc.urdf_text())
    out = {}
    for el in root.findall('link'):
        it = el.find('inertial/inertia')
        iyy = None if it is None else it.get('iyy')
        if iyy is not None:
            out[el.get('name') or ''] = float(iyy)
    return out


def from_description(desc: AnchorDescription, pull: Pull | str = Pull.BACKWARD) -> Multibody:
    """The Multibody of a description (module doc); DescriptionError (one line) when it is not
    a sagittal base with hinged legs."""
    pull = Pull(pull)
    by_parent: dict[str, list[Joint]] = {}
    for jt in desc.joints:
        by_parent.setdefault(jt.parent, []).append(jt)
    dof_of = {}
    names: list[str] = []
    for v in desc.state:
        if v.joints:
            for j in v.joints:
                dof_of[j] = len(names)
            names.append(v.name)
    if not names:
        raise DescriptionError(f'{desc.source}: no state variable drives a joint: nothing to '
                               'move')
    limits = _limits(desc)
    scale = desc.pull_scale.get(pull.value, np.ones(3))
    legs: list[Leg] = []
    for jt in by_parent.get('base_link', []):
        if jt.kind not in ('revolute', 'continuous'):
            continue
        if jt.name not in dof_of:
            raise DescriptionError(f'{desc.source}: joint {jt.name!r} of base_link is not driven '
                                   'by a state variable')
        axis_base = jt.origin[:3, :3] @ jt.axis
        if abs(abs(axis_base[1]) - 1.0) > 1e-6:
            raise DescriptionError(f'{desc.source}: joint {jt.name!r} turns about '
                                   f'{np.round(axis_base, 4).tolist()} in base_link, not about '
                                   'its y axis: the simulation is sagittal')
        mesh = _leg_mesh(desc, jt.child, by_parent, scale if jt.child in desc.pull_links
                         else np.ones(3))
        if mesh is None:
            continue
        lim = limits.get(jt.name) if jt.kind == 'revolute' else None
        if lim is not None and lim[1] - lim[0] >= 2.0 * math.pi - FULL_TURN_TOL:
            lim = None
        legs.append(Leg(jt.name, mesh.facets(), jt.origin[:3, 3].copy(), jt.origin[:3, :3].copy(),
                        jt.axis.copy(), dof=dof_of[jt.name], limits=lim, mesh=mesh))
    if not legs:
        raise DescriptionError(f'{desc.source}: no link hinged to base_link has a mesh: no legs')
    legs = _with_twins(legs)
    base = desc.links['base_link'].mesh
    mass, com, inertia = _mass(desc)
    tether = _fixed_point(desc, desc.tether_link, by_parent)
    order = {k: i for k, i in zip(('LH', 'LF', 'RH', 'RF'), range(len(legs)))}
    return Multibody(
        name=desc.name, base=None if base is None else base.facets(), base_mesh=base,
        legs=tuple(legs), mass=mass, com=com, tether=tether, dof_names=tuple(names),
        char_length=desc.char_length, surface_points=np.asarray(desc.surface_points, float),
        leg_order=order, inertia=inertia,
        notes={'source': str(desc.source), 'inertia': 'URDF inertials (iyy, parallel axes)'})


def _leg_mesh(desc: AnchorDescription, link: str, by_parent: dict, scale: np.ndarray
              ) -> TriMesh | None:
    """The leg link's mesh with every link fixed to it, in the joint frame."""
    parts = []
    stack = [(link, np.eye(4))]
    while stack:
        name, t = stack.pop()
        m = desc.links[name].mesh
        if m is not None:
            if name in desc.pull_links and not np.all(scale == 1.0):
                m = TriMesh(m.vertices * scale, m.faces if np.prod(scale) > 0 else m.faces[:, ::-1])
            parts.append(m.transformed(t[:3, :3], t[:3, 3]))
        for jt in by_parent.get(name, []):
            if jt.kind != 'fixed':
                raise DescriptionError(f'{desc.source}: joint {jt.name!r} moves a link on the leg '
                                       f'{link!r}: legs with knees are beyond this model')
            stack.append((jt.child, t @ jt.origin))
    return TriMesh.concatenate(parts) if parts else None


def _fixed_point(desc: AnchorDescription, link: str, by_parent: dict) -> np.ndarray:
    """Origin of a link fixed to base_link, in base_link (m)."""
    def walk(name: str, t: np.ndarray):
        if name == link:
            return t[:3, 3].copy()
        for jt in by_parent.get(name, []):
            if jt.kind == 'fixed':
                found = walk(jt.child, t @ jt.origin)
                if found is not None:
                    return found
        return None
    p = walk('base_link', np.eye(4))
    if p is None:
        raise DescriptionError(f'{desc.source}: tether link {link!r} is not fixed to base_link')
    return p


def _mass(desc: AnchorDescription) -> tuple[float, np.ndarray, float]:
    """Total mass (kg), centre of mass in base_link (m) and inertia about y through it (kg m^2)
    of every link at joint values zero."""
    values = {v.name: 0.0 for v in desc.state}
    base = desc.base_pose(values)
    posed = desc.pose(values)
    mass = posed.mass
    if not mass > 0.0:
        raise DescriptionError(f'{desc.source}: the URDF gives the robot no mass')
    rot, org = base[:3, :3], base[:3, 3]
    com = rot.T @ (np.asarray(posed.com) - org)
    iyy = _inertia(desc)
    inertia = 0.0
    for link in desc.links.values():
        inertia += iyy.get(link.name, 0.0)
    # parallel axes need each link's centre: the posed composite is enough for the legs'
    # mass near the axis of a small robot; the base's own iyy carries most of it
    return mass, com, inertia


def _with_twins(legs: list[Leg]) -> list[Leg]:
    """Mark mirror pairs: same degree of freedom, hips mirrored in y, frames and axes equal,
    facets mirrored (as sorted sets)."""
    out = list(legs)
    flip = np.array([1.0, -1.0, 1.0])

    def key(c: np.ndarray) -> np.ndarray:
        return c[np.lexsort(np.round(c.T[::-1], 9))]
    for i, a in enumerate(out):
        for j in range(i + 1, len(out)):
            b = out[j]
            if a.twin is not None or b.twin is not None or a.dof != b.dof:
                continue
            if not np.allclose(a.hip * flip, b.hip, atol=1e-9):
                continue
            if len(a.facets) != len(b.facets) or not np.allclose(a.axis_base, b.axis_base):
                continue
            if np.allclose(key(a.facets.centroids * flip), key(b.facets.centroids), atol=1e-9):
                from dataclasses import replace
                out[i] = replace(a, twin=j)
                out[j] = replace(b, twin=i)
    return out
