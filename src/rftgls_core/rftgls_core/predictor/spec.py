"""The one way to build a predictor: a PredictorSpec, checked once by build_predictor.

    spec = PredictorSpec(map='minirquad', pull='backward', edge_method='direct-warm')
    predictor = build_predictor(spec)            # PredictorError (one line) on bad input
    r = predictor.predict(state, phi, 'backward')

What it builds:
    map set, a robot map         MapPredictor, checked for robot, medium, pull, description
    map set, a described map     DescribedMapPredictor (needs the description it was built for)
    map set, + fallback/edge     FallbackPredictor: the map, and a live predictor answering
                                 its out_of_range states and/or its edge-margin answers
    no map, a description        DescriptionPredictor (the live solver on the description)
    no map                       RobotPredictor (the live solver on the robot preset)

Every consumer builds through here: capacity_node and behavior_node (their parameters), the
lab tools (their options), the simulator's ground, the `rftgls` CLI. Errors name the inputs the
way the caller's user wrote them (InputNames: a node parameter, a command-line flag).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rftgls_conventions import one_line

if TYPE_CHECKING:
    from ..description import AnchorDescription
    from ..rft.media import Medium
    from .live import LivePredictor
    from .protocol import Predictor

DEFAULT_ROBOT = 'minirquad'
# The medium a robot preset is anchored in unless told otherwise (the paper's two set-ups).
ROBOT_MEDIUM = {'prototype': 'glass_beads', 'minirquad': 'm90_sand'}


class PredictorError(ValueError):
    """A specification that cannot be built (one line, naming the input at fault)."""


@dataclass(frozen=True)
class InputNames:
    """How the caller's user names each input of a PredictorSpec, so that a build error speaks
    their language (capacity_node: its parameters; the CLI: its flags). verb: what the user
    does to give an input ('set' a parameter, 'give' a flag). state_source: where the
    AnchorState that feeds a description comes from (said when it cannot feed it)."""

    map: str = 'map'
    robot: str = 'robot'
    description: str = 'description'
    state_map: str = 'state_map'
    medium: str = 'medium'
    pull: str = 'pull'
    live_method: str = 'live_method'
    fallback_method: str = 'fallback_method'
    edge_method: str = 'edge_method'
    n_twists: str = 'n_twists'
    verb: str = 'give'
    state_source: str = 'the AnchorState quantities h, theta_b, theta_l1, theta_l2 feed it'


@dataclass(frozen=True)
class PredictorSpec:
    """What a predictor answers with.

    map: a map file, a shipped map's file name or a robot name (maps.resolve_map); '' = the
        live solver. A robot map (`rftgls map build`) and a described map (`--anchor`) are
        told apart by their schema.
    robot: the robot preset the live solver poses, and the robot a robot map must be built for
        (None: a map of any robot; the live solver then poses DEFAULT_ROBOT).
    description: an anchor description (YAML path, or loaded) posed instead of the robot; a
        map must answer for it. state_map: which AnchorState quantity feeds each of its state
        variables ('NAME=QUANTITY,...', a mapping, or None: the variables' own names).
    medium: a preset name, a medium JSON file or a Medium. The live solver's medium (None: the
        description's, else ROBOT_MEDIUM of the robot); a map must be built for a medium named
        here (None or a Medium: no check).
    pull: the pull orientation ('forward', 'backward') a map must hold (None: no check).
    live_method: the live solver's method when there is no map (surfaces/registry.py: every
        registered method, 'direct-warm' included; default DEFAULT_METHOD).
    fallback_method: with a map, the live method answering its out_of_range states ('': none).
    edge_method: with a map, the live method re-answering its edge-margin answers ('': none);
        the same method as fallback_method shares one solver.
    n_twists: sampled unit twists per state: one count for every method, or a count per method
        name (the method that answers: a description answers a streaming method with its
        surface method); None or a name left out: that method's default (default_twists).
    model: the RFT stress law ('agarwal', 'li').
    mass_scale: multiplies the anchor's mass (the simulator's heavier or lighter true robot).
    """

    map: str = ''
    robot: str | None = DEFAULT_ROBOT
    description: str | Path | AnchorDescription | None = None
    state_map: str | Mapping[str, str] | None = None
    medium: str | Medium | None = None
    pull: str | None = None
    live_method: str = 'twist-mesh'      # registry.DEFAULT_METHOD (this module imports light)
    fallback_method: str = ''
    edge_method: str = ''
    n_twists: int | Mapping[str, int] | None = None
    model: str = 'agarwal'
    mass_scale: float = 1.0


def build_predictor(spec: PredictorSpec, names: InputNames = InputNames()) -> Predictor:
    """The predictor of `spec` (see the module doc); PredictorError, one line naming the input
    in the caller's words (`names`), when it cannot be built."""
    return _Builder(spec, names).build()


class _Builder:
    """One build: the description and medium are loaded once and shared by every part."""

    def __init__(self, spec: PredictorSpec, names: InputNames):
        self.spec = spec
        self.names = names
        self._desc: AnchorDescription | None = None
        self._state_map: Mapping[str, str] | None = None
        self._medium: Medium | None = None

    # -- the whole ----------------------------------------------------------------------------
    def build(self) -> Predictor:
        s, n = self.spec, self.names
        self._check()
        if not s.map.strip():
            return self.live(s.live_method, n.live_method)
        from .maps import FallbackPredictor
        primary = self.map()
        oor, edge = s.fallback_method.strip(), s.edge_method.strip()
        fallback = self.live(oor, n.fallback_method) if oor else None
        checker = ((fallback if edge == oor else self.live(edge, n.edge_method))
                   if edge else None)
        if fallback is None and checker is None:
            return primary
        return FallbackPredictor(primary, fallback, checker)

    def _check(self) -> None:
        s, n = self.spec, self.names
        if s.state_map is not None and s.description is None:
            raise PredictorError(f'{n.state_map} needs {n.description}')
        if not (math.isfinite(s.mass_scale) and s.mass_scale > 0.0):
            raise PredictorError(f'mass scale must be a positive number, got {s.mass_scale}')
        counts = (s.n_twists.values() if isinstance(s.n_twists, Mapping)
                  else [] if s.n_twists is None else [s.n_twists])
        for c in counts:
            if not (isinstance(c, int) and c > 0):
                raise PredictorError(f'{n.n_twists} must be a positive count, got {c!r}')

    # -- parts --------------------------------------------------------------------------------
    def description(self) -> AnchorDescription:
        """The loaded description of the spec (and its state map, checked: parse only)."""
        from ..description import (
            AnchorDescription,
            DescriptionError,
            load_description,
            parse_state_map,
        )
        s, n = self.spec, self.names
        if self._desc is None:
            assert s.description is not None
            try:
                self._desc = (s.description if isinstance(s.description, AnchorDescription)
                              else load_description(s.description))
            except DescriptionError as exc:
                raise PredictorError(f'{n.description}: {one_line(exc)}') from exc
            try:
                self._state_map = (parse_state_map(s.state_map) if isinstance(s.state_map, str)
                                   else s.state_map)
            except DescriptionError as exc:
                raise PredictorError(f'{n.state_map}: {one_line(exc)}') from exc
        return self._desc

    def not_fed(self, exc: Exception) -> PredictorError:
        """The error of a description the AnchorState cannot feed."""
        return PredictorError(f'{self.names.description}: {self.names.state_source}: '
                              f'{one_line(exc)}')

    def medium(self) -> Medium:
        from ..rft.media import Medium, load_medium
        s = self.spec
        if self._medium is None:
            if isinstance(s.medium, Medium):
                self._medium = s.medium
            else:
                name = (s.medium or (self.description().medium if s.description is not None
                                     else ROBOT_MEDIUM.get(s.robot or DEFAULT_ROBOT, '')))
                try:
                    self._medium = load_medium(name)
                except ValueError as exc:
                    raise PredictorError(f'{self.names.medium}: {one_line(exc)}') from exc
        return self._medium

    def twists(self, method: str) -> int | None:
        c = self.spec.n_twists
        return c.get(method) if isinstance(c, Mapping) else c

    def live(self, method: str, role: str) -> LivePredictor:
        """The live predictor of `method` (its input named `role` in errors)."""
        from ..description import DescriptionError
        from ..robots.presets import get_robot
        from ..surfaces.registry import surface_method
        from .live import DescriptionPredictor, RobotPredictor
        s = self.spec
        try:
            answering = surface_method(method)
        except ValueError as exc:
            raise PredictorError(f'{role}: {one_line(exc)}') from exc
        try:
            if s.description is not None:
                desc = self.description()
                try:
                    return DescriptionPredictor(desc, self.medium(), s.model, answering,
                                                self.twists(answering), mass_scale=s.mass_scale,
                                                state_map=self._state_map)
                except DescriptionError as exc:
                    raise self.not_fed(exc) from exc
            try:
                robot = get_robot(s.robot or DEFAULT_ROBOT)
            except (KeyError, ValueError) as exc:
                raise PredictorError(f'{self.names.robot}: {one_line(exc)}') from exc
            if s.mass_scale != 1.0:
                robot = dataclasses.replace(robot, mass=robot.mass * s.mass_scale)
            return RobotPredictor(robot, self.medium(), s.model, method, self.twists(method))
        except PredictorError:
            raise
        except (ValueError, ImportError, AttributeError) as exc:
            # AttributeError: a surface class the registry names but the core lacks.
            raise PredictorError(f'cannot build the live {method!r} predictor: '
                                 f'{one_line(exc)}') from exc

    def map(self) -> Predictor:
        """The map predictor of the spec, checked for what it must answer for."""
        from ..maps import CapacityMap, MapFileError, resolve_map
        from ..maps.described import DescribedMap, is_described_map
        from .maps import DescribedMapPredictor, MapPredictor
        s, n = self.spec, self.names
        try:
            path = resolve_map(s.map.strip())
        except MapFileError as exc:
            raise PredictorError(f'map file not found: {one_line(exc)}; build it with `rftgls '
                                 'map build` or use the live solver') from exc
        if is_described_map(path):
            if s.description is None:
                raise PredictorError(f'map file {path} is a described map: {n.verb} '
                                     f'{n.description} (the description it was built for)')
            cmap: Any = self._load(DescribedMap, path)
            try:
                out: Any = DescribedMapPredictor(cmap, self.description(), self._state_map,
                                                 path)
            except ValueError as exc:
                from ..description import DescriptionError
                if isinstance(exc, DescriptionError):
                    raise self.not_fed(exc) from exc
                raise PredictorError(f'map file {path} does not answer for {n.description}: '
                                     f'{one_line(exc)}') from exc
            self._check_map(path, None, cmap.medium_name)
            self._check_pulls(path, cmap.grid.pulls)
            return out
        cmap = self._load(CapacityMap, path)
        self._check_map(path, cmap.robot_name, cmap.medium_name)
        if s.description is not None:
            try:
                cmap.check_description(self.description().sha256)
            except ValueError as exc:
                raise PredictorError(f'map file {path} does not answer for {n.description}: '
                                     f'{one_line(exc)}') from exc
        self._check_pulls(path, cmap.pulls)
        return MapPredictor(cmap, path)

    def _load(self, cls, path: Path):
        from ..maps import MapFileError
        try:
            return cls.load(path)
        except OSError as exc:             # not HDF5 at all
            raise PredictorError(f'cannot read map file {path}: {one_line(exc)}') from exc
        except (MapFileError, ValueError, KeyError, TypeError) as exc:
            # wrong schema, truncated file, failed integrity check, anything else refused
            raise PredictorError(f'bad map file {path}: {one_line(exc)}') from exc

    def _check_map(self, path: Path, robot: str | None, medium: str) -> None:
        """A map answers only for what it was built for: its robot and medium."""
        s, n = self.spec, self.names
        checks = [('medium', n.medium, s.medium if isinstance(s.medium, str) else None,
                   medium)]
        if robot is not None:
            checks.insert(0, ('robot', n.robot, s.robot, robot))
        for what, name, want, have in checks:
            if want is not None and want.strip().lower() != str(have).lower():
                raise PredictorError(f'map file {path} is for {what} {have!r}, not for {name} '
                                     f'{want!r}')

    def _check_pulls(self, path: Path, pulls: tuple[str, ...]) -> None:
        s = self.spec
        if s.pull is not None and str(s.pull) not in pulls:
            raise PredictorError(f'map file {path} holds pulls {list(pulls)}, not '
                                 f'{str(s.pull)!r}')
