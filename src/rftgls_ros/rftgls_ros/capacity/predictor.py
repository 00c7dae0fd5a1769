"""Predictors behind capacity_node and behavior_node: a precomputed HDF5 map (default) or the
live core model, both implementing rftgls_core.predictor.Predictor:
  state: rftgls_core AnchorState (h m, theta_b rad, theta_l1 rad, theta_l2 rad),
  phi:   tether angle, rad (tension along (-cos phi, 0, sin phi) in world axes),
  pull:  'forward' | 'backward' (C-leg orientation relative to the pull).
The result carries a status (ok / out_of_range / unsupported / ...) and values only when the
status has one (rftgls_core.surfaces.base.CapacityResult). A map answers `out_of_range` (no
value) outside its grid; `LiveFallback` lets the live solver answer those states instead.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from rftgls_conventions import one_line
from rftgls_core.predictor import Predictor
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.surfaces.registry import PREDICTOR_METHODS
from rftgls_core.types import AnchorState, Pull, Status
from rftgls_node_base.parameters import ConfigError

# The installed (shipped) map; rftgls_core.maps.resolve_map maps this name to maps_dir().
DEFAULT_MAP = 'maps/minirquad_m90_sand.h5'
# The warm-started direct solver (surfaces/warm.py) first, then every registered method that
# is not a reference only.
LIVE_METHODS = ('direct-warm',) + PREDICTOR_METHODS


def predictor_name(predictor: Predictor) -> str:
    """A short label for logs and diagnostics: the predictor's `name` attribute if it has one
    (this module's predictors do), else its class name."""
    return str(getattr(predictor, 'name', type(predictor).__name__))


class LivePredictor:
    """rftgls_core.predictor.live.RobotPredictor computed per call (about 10 ms for
    twist-mesh), or for 'direct-warm' the core's warm-started direct (WarmAnchorModel: the
    cold direct's answers, under a millisecond per message on a streaming robot; `stats()`
    for diagnostics).
    n_twists None: DEFAULT_TWISTS for every method (not the model's per-method default)."""

    def __init__(self, robot: str = 'minirquad', medium: str = 'm90_sand',
                 method: str = 'direct', n_twists: int | None = None):
        from rftgls_core.predictor.live import RobotPredictor
        from rftgls_core.rft.media import get_medium
        from rftgls_core.robots.presets import get_robot
        from rftgls_core.surfaces.registry import DEFAULT_TWISTS
        if method == 'direct-warm':
            self.model = RobotPredictor(get_robot(robot), get_medium(medium), method=method,
                                        n_twists=n_twists)
            self.stats = self.model.stats
        else:
            self.model = RobotPredictor(get_robot(robot), get_medium(medium), method=method,
                                     n_twists=n_twists or DEFAULT_TWISTS)
        self.name = f'live:{method}'

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.model.predict(state, phi, pull)


# What feeds each estimate of the node (docs/design/capacity-inputs.md): a description's state
# variables can only be fed from these.
ESTIMATE_SOURCES = {'h': 'height_topic (or height_m)', 'theta_b': 'imu_topic or pitch_topic',
                    'theta_l1': 'joint_states (joint_proximal_*)',
                    'theta_l2': 'joint_states (joint_distal_*)'}


def parse_state_variables(text: str) -> dict[str, str] | None:
    """`anchor_state_variables` 'NAME=ESTIMATE,...' -> {NAME: ESTIMATE}; '' -> None (the
    description's own names). ConfigError (one line) on a malformed entry."""
    from rftgls_core.description import DescriptionError, parse_state_map
    try:
        return parse_state_map(text)
    except DescriptionError as exc:
        raise ConfigError(f'anchor_state_variables: {one_line(exc)}') from exc


class DescriptionPredictor:
    """The live solver on an anchor description (ROS parameter `anchor_description_file` = path of
    its YAML): rftgls_core.description.DescriptionModel, RobotPredictor's interface on the posed
    description. The node estimates (h, theta_b, theta_l1, theta_l2) from its inputs
    (ESTIMATE_SOURCES), so every state variable of the description must be fed by one of
    them: by its name, or by `anchor_state_variables` (state_map here, NAME -> estimate); a
    description using only some (a two-variable body: h and theta_b) leaves the others out,
    their inputs are still checked. For a shipped robot it gives the numbers of LivePredictor
    (tests/ros/test_description_predictor.py)."""

    def __init__(self, path: str, medium: str = '', method: str = 'direct',
                 n_twists: int | None = None, state_map: dict[str, str] | None = None):
        from rftgls_core.description import DescriptionError
        from rftgls_core.predictor.live import DescriptionPredictor as DescriptionModel
        from rftgls_core.rft.media import get_medium
        from rftgls_core.surfaces.registry import DEFAULT_TWISTS
        desc = _description(path)
        # 'direct-warm' (integ's warm-started direct, the cold direct's answers) has no
        # description variant yet: the cold direct answers the same, only slower.
        method = 'direct' if method == 'direct-warm' else method
        try:
            self.model = DescriptionModel(desc, get_medium(medium or desc.medium),
                                          method=method, n_twists=n_twists or DEFAULT_TWISTS,
                                          state_map=state_map)
        except DescriptionError as exc:
            feeds = '; '.join(f'{k} <- {v}' for k, v in ESTIMATE_SOURCES.items())
            raise ConfigError(f'anchor_description_file: capacity_node estimates h, theta_b, '
                              f'theta_l1, theta_l2 ({feeds}) and feeds a description\'s state '
                              f'variables from them by name or anchor_state_variables: '
                              f'{one_line(exc)}') from exc
        self.description = desc
        self.name = f'live:{method}:{desc.name}'

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.model.predict(state, phi, pull)


def _description(path: str):
    """The loaded description of the `anchor_description_file` parameter (ConfigError, one line)."""
    from rftgls_core.description import DescriptionError, load_description
    try:
        return load_description(path)
    except DescriptionError as exc:
        raise ConfigError(f'anchor_description_file: {one_line(exc)}') from exc


def resolve_map_path(path: str) -> Path:
    """rftgls_core.maps.resolve_map (the one resolver: explicit path, then the installed maps,
    never the current directory implicitly); MapFileError when there is no such map."""
    from rftgls_core.maps import resolve_map
    return resolve_map(path)


class MapPredictor:
    """Interpolation in a precomputed state-space map (about 20 us per query).

    robot, medium, pull: what the node is configured for; a map made for something else is
    refused at start-up rather than answering questions about another robot.
    """

    def __init__(self, path: str | os.PathLike = DEFAULT_MAP, robot: str | None = None,
                 medium: str | None = None, pull: str | None = None,
                 description_sha256: str | None = None):
        from rftgls_core.maps import CapacityMap, MapFileError
        try:
            self.path = resolve_map_path(str(path))
        except MapFileError as exc:
            raise ConfigError(f'map file not found: {exc}; build it with `rftgls map build` '
                              'or set map_file to "" for live computation') from exc
        try:
            self.map = CapacityMap.load(self.path)
        except MapFileError as exc:  # wrong schema, truncated file, failed integrity check
            raise ConfigError(f'bad map file {self.path}: {one_line(exc)}') from exc
        except OSError as exc:  # not HDF5 at all
            raise ConfigError(f'cannot read map file {self.path}: {one_line(exc)}') from exc
        except (ValueError, KeyError, TypeError) as exc:  # anything else the loader refuses
            raise ConfigError(f'bad map file {self.path}: {one_line(exc)}') from exc
        # 'shipped' / 'verified': the loader checked the content hash; 'unverified': a map
        # with no hash, whose integrity nobody can check (the node logs it loudly).
        self.integrity = self.map.data.integrity
        checks = (('robot', robot, self.map.robot_name), ('medium', medium, self.map.medium_name))
        for what, want, have in checks:
            if want is not None and want.strip().lower() != str(have).lower():
                raise ConfigError(f'map file {self.path} is for {what} {have!r}, '
                                  f'the node is configured for {want!r}')
        if description_sha256 is not None:
            try:
                self.map.check_description(description_sha256)
            except ValueError as exc:
                raise ConfigError(f'map file {self.path} does not answer for '
                                  f'anchor_description_file: {one_line(exc)}') from exc
        if pull is not None and str(pull) not in self.map.pulls:
            raise ConfigError(f'map file {self.path} holds pulls {list(self.map.pulls)}, '
                              f'not {str(pull)!r}')
        self.name = f'map:{self.path.name}'

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.map.query(state, phi, pull)


class DescribedMapPredictor:
    """A described map (`rftgls map build --anchor`, maps/described.py) for the description
    of `anchor_description_file`: rftgls_core's DescribedMapModel (the node's estimates feed
    the description's variables by name or anchor_state_variables). The map must answer for
    that description (identity) and be built for the node's medium and pull."""

    def __init__(self, path: Path, desc, medium: str | None = None, pull: str | None = None,
                 state_map: dict[str, str] | None = None):
        from rftgls_core.description import DescriptionError
        from rftgls_core.maps import MapFileError
        from rftgls_core.maps.described import DescribedMap, DescribedMapModel
        try:
            cmap = DescribedMap.load(path)
        except MapFileError as exc:
            raise ConfigError(f'bad map file {path}: {one_line(exc)}') from exc
        try:
            self.model = DescribedMapModel(cmap, desc, state_map)
        except DescriptionError as exc:
            feeds = '; '.join(f'{k} <- {v}' for k, v in ESTIMATE_SOURCES.items())
            raise ConfigError(f'anchor_description_file: capacity_node estimates h, theta_b, '
                              f'theta_l1, theta_l2 ({feeds}): {one_line(exc)}') from exc
        except ValueError as exc:
            raise ConfigError(f'map file {path} does not answer for anchor_description_file: '
                              f'{one_line(exc)}') from exc
        if medium is not None and medium.strip().lower() != cmap.medium_name.lower():
            raise ConfigError(f'map file {path} is for medium {cmap.medium_name!r}, the node '
                              f'is configured for {medium!r}')
        if pull is not None and str(pull) not in cmap.grid.pulls:
            raise ConfigError(f'map file {path} holds pulls {list(cmap.grid.pulls)}, '
                              f'not {str(pull)!r}')
        self.path = Path(path)
        self.integrity = 'verified'   # load_described_map checked its content hash
        self.name = f'map:{self.path.name}:{desc.name}'

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.model.predict(state, phi, pull)


def _described_map(map_file: str, desc_path: str, medium: str, pull: str | None,
                   state_map: dict[str, str] | None) -> DescribedMapPredictor | None:
    """The described-map predictor when map_file names a described map, else None."""
    from rftgls_core.maps import MapFileError
    from rftgls_core.maps.described import is_described_map
    try:
        path = resolve_map_path(map_file)
    except MapFileError:
        return None                      # MapPredictor says so, in its words
    if not is_described_map(path):
        return None
    if not desc_path:
        raise ConfigError(f'map file {path} is a described map: set anchor_description_file '
                          'to the description it was built for')
    return DescribedMapPredictor(path, _description(desc_path), medium, pull, state_map)


class LiveFallback:
    """A map, with a live solver answering where the map cannot be trusted on its own:

    * `out_of_range` (outside its grid), when `fallback` is set: the live answer, reason
      `live_fallback`;
    * an answer of the edge-margin rule (flag `edge_margin`, a cell next to the support edge
      answered from an interpolated support margin), when `edge` is set: the live answer,
      reason `live_edge_check`. The interpolated margin can say "holds" where the anchor
      holds nothing (maps/README.md: one state in 1,800 random MiniRQuad states, 0.51 N
      against `unsupported`); the live solver decides there. Its answer replaces the map's
      whether lower or higher (the edge-margin value is a deliberately low bound, the live
      one exact).

    Every other map answer stands; the live answer's reason keeps the solver's own reason
    first, if any. One solver may serve both (pass the same object)."""

    def __init__(self, primary: Predictor, fallback: Predictor | None = None,
                 edge: Predictor | None = None):
        self.primary = primary
        self.fallback = fallback
        self.edge = edge
        parts = [predictor_name(primary)]
        if fallback is not None:
            parts.append(predictor_name(fallback))
        if edge is not None:
            parts.append(('' if edge is fallback else predictor_name(edge)) + '(edge check)')
        self.name = '+'.join(parts)

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        r = self.primary.predict(state, phi, pull)
        if r.status is Status.OUT_OF_RANGE and self.fallback is not None:
            live, why = self.fallback, 'live_fallback'
        elif self.edge is not None and 'edge_margin' in r.flags:
            live, why = self.edge, 'live_edge_check'
        else:
            return r
        answer = live.predict(state, phi, pull)
        reason = ';'.join(x for x in (answer.reason, why) if x)
        return dataclasses.replace(answer, reason=reason)


def predictor_from_params(map_file: str, live_method: str = 'direct',
                          robot: str | None = 'minirquad', medium: str = 'm90_sand',
                          n_twists: int = 0, pull: str | None = None,
                          out_of_range_live_method: str = '',
                          anchor_description_file: str = '',
                          anchor_state_variables: str = '',
                          edge_live_method: str = '') -> Predictor:
    """capacity_node's predictor from its parameters: the map predictor when map_file is set
    (with the live solver `out_of_range_live_method` answering outside its grid when that is
    set, and `edge_live_method` re-answering its edge-margin answers), else the live one.
    robot: the preset the node is configured for (None: a map of any robot, checked against
    the description when one is given). anchor_description_file: path
    of an anchor description YAML for the live solver (and the identity a map must answer
    for); '' = the `robot` preset; anchor_state_variables: which estimate feeds which of its
    variables (parse_state_variables). Raises ConfigError."""
    desc = anchor_description_file.strip()
    live_robot = robot or 'minirquad'     # None only frees a map's robot check
    state_map = parse_state_variables(anchor_state_variables)
    if state_map is not None and not desc:
        raise ConfigError('anchor_state_variables needs anchor_description_file')
    if map_file.strip():
        cmap: Predictor | None = _described_map(map_file.strip(), desc, medium, pull, state_map)
        if cmap is None:
            sha = _description(desc).sha256 if desc else None
            cmap = MapPredictor(map_file.strip(), robot, medium, pull, description_sha256=sha)
        oor, edge = out_of_range_live_method.strip(), edge_live_method.strip()
        fallback = (_live(live_robot, medium, oor, n_twists, 'out_of_range_live_method', desc,
                          state_map) if oor else None)
        checker = (fallback if edge == oor else
                   _live(live_robot, medium, edge, n_twists, 'edge_live_method', desc,
                         state_map)) if edge else None
        if fallback is None and checker is None:
            return cmap
        return LiveFallback(cmap, fallback, checker)
    return _live(live_robot, medium, live_method, n_twists, 'live_method', desc, state_map)


def _live(robot: str, medium: str, live_method: str, n_twists: int,
          param: str, anchor_description_file: str = '',
          state_map: dict[str, str] | None = None) -> LivePredictor | DescriptionPredictor:
    if live_method not in LIVE_METHODS:
        raise ConfigError(f'{param} must be one of {", ".join(LIVE_METHODS)}, '
                          f'got {live_method!r}')
    if n_twists < 0:
        raise ConfigError(f'live_n_twists must be >= 0 (0 = DEFAULT_TWISTS), got {n_twists}')
    try:
        if anchor_description_file:
            return DescriptionPredictor(anchor_description_file, medium, live_method,
                                        n_twists or None, state_map)
        return LivePredictor(robot, medium, live_method, n_twists or None)
    except ConfigError:
        raise
    except (ValueError, ImportError, AttributeError) as exc:
        # AttributeError: a surface class the core names but does not (yet) provide.
        raise ConfigError(f'cannot build the live {live_method!r} predictor: {exc}') from exc
