"""The state grid of a capacity map: four state axes, pull angles and pull orientations.

Axes (all SI, strictly increasing, at least two nodes each so every query has a cell):
    h         height of the winch point p above the free surface, m (positive up; the legs
              reach ~0.09 m below the axles, so small positive h still buries them)
    theta_b   body pitch, rad
    theta_l1  proximal leg angle, rad
    theta_l2  distal leg angle, rad
    phi       pull angles of the tether, rad (types.pull_direction)
    pulls     pull orientations ('forward', 'backward'); not interpolated

Node order is C order over (h, theta_b, theta_l1, theta_l2): the flat state index k is
((i_h * n_b + i_b) * n_l1 + i_l1) * n_l2 + i_l2. Every builder and file uses that order.

Degrees and millimetres appear only in `from_degrees` / `parse_range` (the CLI edge).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..types import AnchorState, Pull

STATE_AXES = ('h', 'theta_b', 'theta_l1', 'theta_l2')
AXIS_UNITS = {'h': 'm', 'theta_b': 'rad', 'theta_l1': 'rad', 'theta_l2': 'rad', 'phi': 'rad'}
# Human-facing unit of each axis and the factor SI value * factor = human value.
AXIS_HUMAN = {'h': ('mm', 1e3), 'theta_b': ('deg', 180.0 / math.pi),
              'theta_l1': ('deg', 180.0 / math.pi), 'theta_l2': ('deg', 180.0 / math.pi),
              'phi': ('deg', 180.0 / math.pi)}
ALL_PULLS = (Pull.FORWARD.value, Pull.BACKWARD.value)


def check_axis(name: str, values) -> np.ndarray:
    """A float64 copy of an axis, or ValueError: 1-D, >= 2 nodes, finite, strictly increasing."""
    a = np.array(values, dtype=np.float64).reshape(-1)
    if a.size < 2:
        raise ValueError(f'axis {name}: needs at least 2 nodes, got {a.size}')
    if not np.all(np.isfinite(a)):
        raise ValueError(f'axis {name}: values must be finite')
    if not np.all(np.diff(a) > 0.0):
        raise ValueError(f'axis {name}: values must be strictly increasing')
    return a


# Nodes of one axis given on a command line: a map of 1000 nodes on one axis alone is already
# 1000 states per combination of the others; more is a typo in the step.
MAX_AXIS_NODES = 1000


def parse_range(text: str) -> np.ndarray:
    """'start:step:stop' (inclusive stop) or 'a,b,c' -> float64 array, in the caller's units.

    Node i is start + i*step (not a running sum), so the same text always gives the same bits.
    """
    text = text.strip()
    try:
        if ':' in text:
            parts = [float(p) for p in text.split(':')]
            if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
                raise ValueError
            start, step, stop = parts
            if not (step > 0.0 and stop >= start):
                raise ValueError
            n = (stop - start) / step + 1e-9
            if not n < MAX_AXIS_NODES:
                raise ValueError(f'more than {MAX_AXIS_NODES} nodes')
            return start + step * np.arange(int(math.floor(n)) + 1, dtype=np.float64)
        values = np.array([float(p) for p in text.split(',') if p.strip()], dtype=np.float64)
        if not np.all(np.isfinite(values)) or len(values) > MAX_AXIS_NODES:
            raise ValueError
        return values
    except ValueError as exc:
        why = f' ({exc})' if str(exc) else ''
        raise ValueError(f'bad range {text!r}{why}: use start:step:stop (step > 0) or a,b,c '
                         'of finite numbers') from None


def check_pulls(pulls: tuple[str, ...]) -> tuple[str, ...]:
    """pulls unchanged when distinct and non-empty; ValueError otherwise."""
    if not pulls or len(set(pulls)) != len(pulls):
        raise ValueError(f'pulls must be distinct and non-empty, got {pulls!r}')
    return pulls


class _HasAxes(Protocol):
    @property
    def axes(self) -> tuple[np.ndarray, ...]: ...
    @property
    def phi(self) -> np.ndarray: ...
    @property
    def pulls(self) -> tuple[str, ...]: ...


class GridShape:
    """Array shapes of a map grid with `axes` (state axes in order), `phi` and `pulls`; shared
    by the robot grid and the described grid, whose answer arrays are laid out alike."""

    @property
    def state_shape(self: _HasAxes) -> tuple[int, ...]:
        return tuple(len(a) for a in self.axes)

    @property
    def n_states(self: _HasAxes) -> int:
        return int(np.prod([len(a) for a in self.axes]))

    @property
    def shape(self: _HasAxes) -> tuple[int, ...]:
        """Shape of a per-answer array: (n_pull, *state axes, n_phi)."""
        return (len(self.pulls),) + tuple(len(a) for a in self.axes) + (len(self.phi),)


@dataclass(frozen=True, eq=False)
class MapGrid(GridShape):
    """State axes (m, rad), pull angles phi (rad) and pull orientations of a map."""

    h: np.ndarray
    theta_b: np.ndarray
    theta_l1: np.ndarray
    theta_l2: np.ndarray
    phi: np.ndarray
    pulls: tuple[str, ...] = ALL_PULLS

    def __post_init__(self) -> None:
        for name in STATE_AXES + ('phi',):
            a = check_axis(name, getattr(self, name))
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, 'pulls', check_pulls(tuple(Pull(p).value
                                                            for p in self.pulls)))

    def __eq__(self, other) -> bool:
        return (isinstance(other, MapGrid) and self.pulls == other.pulls
                and all(np.array_equal(getattr(self, n), getattr(other, n))
                        for n in STATE_AXES + ('phi',)))

    @classmethod
    def from_degrees(cls, h_mm, theta_b_deg, theta_l1_deg, theta_l2_deg, phi_deg,
                     pulls=ALL_PULLS) -> 'MapGrid':
        """The CLI edge: h in mm, angles in degrees."""
        return cls(h=np.asarray(h_mm, dtype=float) * 1e-3,
                   theta_b=np.radians(theta_b_deg), theta_l1=np.radians(theta_l1_deg),
                   theta_l2=np.radians(theta_l2_deg), phi=np.radians(phi_deg), pulls=pulls)

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (self.h, self.theta_b, self.theta_l1, self.theta_l2)

    def state(self, k: int) -> AnchorState:
        """The anchor state of flat (C-order) state index k."""
        i = np.unravel_index(int(k), self.state_shape)
        return AnchorState(*(float(a[j]) for a, j in zip(self.axes, i)))

    def state_array(self) -> np.ndarray:
        """(n_states, 4) all states in flat order (h, theta_b, theta_l1, theta_l2)."""
        mesh = np.meshgrid(*self.axes, indexing='ij')
        return np.stack([m.reshape(-1) for m in mesh], axis=1)

    def describe(self) -> str:
        parts = []
        for name in STATE_AXES + ('phi',):
            unit, f = AXIS_HUMAN[name]
            a = getattr(self, name) * f
            parts.append(f'{name} {a[0]:g}..{a[-1]:g} {unit} ({len(a)})')
        return ', '.join(parts) + f'; pulls {",".join(self.pulls)}; {self.n_states} states'


# Paper sec. III-E: thetaL1,L2 = -40:20:40 deg, thetaB = -20:10:20 deg, h = 5:5:30 mm.
DEFAULT_PHI_DEG = np.arange(-30.0, 10.0 + 1e-9, 10.0)   # includes 0 and -20 (paper Fig. 10)


def prototype_grid(phi_deg=DEFAULT_PHI_DEG) -> MapGrid:
    """The paper's prototype grid: 6 x 5 x 5 x 5 = 750 states."""
    return MapGrid.from_degrees(5.0 + 5.0 * np.arange(6), -20.0 + 10.0 * np.arange(5),
                                -40.0 + 20.0 * np.arange(5), -40.0 + 20.0 * np.arange(5),
                                phi_deg)


def minirquad_grid(phi_deg=DEFAULT_PHI_DEG) -> MapGrid:
    """A grid around the paper's Table II anchors and the planner's gaits (final poses),
    7 x 7 x 4 x 8 = 1,568 states.

    Table II: DH (thetaL1, thetaL2) = (-40, 30) deg, thetaB 5.0 deg, h 34 mm;
    DL (-40, 0), 8.9 deg, 36 mm; SH (-40, 30), 2.4 deg, 47 mm. The grid puts both leg poses
    on nodes (thetaL1 -60:20:0, thetaL2 -30:10:40 deg) and brackets the measured body angle
    and depth spreads (h 25:5:55 mm) by at least one cell. The pitch axis, -5:5:25 deg, reaches
    past the pitches the burrow simulation predicts for the planner's gaits (up to about 16
    deg) by more than capacity_node's pitch band (one sigma, 1 deg): a pose predicted or
    measured at the old edge, 15 deg, had no lower bound there. Every final leg
    pose the burrow planner can command (planning.gaits.SHIPPED_GRID and the paper's modes)
    lies at least one leg step (10 deg) inside the leg axes: legs that stop a servo count past
    a commanded pose must still be on the map, else the tug check answers out_of_range for
    the whole anchor (tests/core/test_maps_cover_gaits.py).
    """
    return MapGrid.from_degrees(25.0 + 5.0 * np.arange(7), -5.0 + 5.0 * np.arange(7),
                                -60.0 + 20.0 * np.arange(4), -30.0 + 10.0 * np.arange(8),
                                phi_deg)


DEFAULT_GRIDS = {'prototype': prototype_grid, 'minirquad': minirquad_grid}


def default_grid(robot_name: str, phi_deg=DEFAULT_PHI_DEG) -> MapGrid:
    key = robot_name.strip().lower()
    if key not in DEFAULT_GRIDS:
        raise ValueError(f'no default grid for robot {robot_name!r}; give every axis '
                         f'(known: {", ".join(sorted(DEFAULT_GRIDS))})')
    return DEFAULT_GRIDS[key](phi_deg)
