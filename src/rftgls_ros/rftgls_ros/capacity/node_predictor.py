"""capacity_node's predictor from its parameters: one rftgls_core PredictorSpec, built once.

    map_file, robot, medium, pull, live_method, out_of_range_live_method, edge_live_method,
    live_n_twists, anchor_description_file, anchor_state_variables
        -> rftgls_core.predictor.PredictorSpec -> build_predictor -> a Predictor

The predictor answers predict(state, phi, pull) with a status (rftgls_core.predictor):
  state: rftgls_core AnchorState (h m, theta_b rad, theta_l1 rad, theta_l2 rad),
  phi:   tether angle, rad (tension along (-cos phi, 0, sin phi) in world axes),
  pull:  'forward' | 'backward' (C-leg orientation relative to the pull).
A map answers `out_of_range` (no value) outside its grid; out_of_range_live_method lets the
live solver answer those states instead, edge_live_method re-answers the map's edge-margin
answers. Any error names the parameter at fault, in one line (ConfigError: the node exits 2).
behavior_node's own map (capacity_source local_map) is built the same way.
"""
from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

from rftgls_core.predictor import InputNames, Predictor, PredictorError, PredictorSpec
from rftgls_core.predictor import build_predictor as build
from rftgls_core.surfaces.registry import DEFAULT_TWISTS, LIVE_METHODS, PREDICTOR_METHODS
from rftgls_core.types import AnchorState
from rftgls_node_base.parameters import ConfigError

# The installed (shipped) map; rftgls_core.maps.resolve_map maps this name to maps_dir().
DEFAULT_MAP = 'maps/minirquad_m90_sand.h5'

# What feeds each estimate of the node (docs/design/capacity-inputs.md): a description's state
# variables can only be fed from these.
ESTIMATE_SOURCES = {'h': 'height_topic (or height_m)', 'theta_b': 'imu_topic or pitch_topic',
                    'theta_l1': 'joint_states (joint_proximal_*)',
                    'theta_l2': 'joint_states (joint_distal_*)'}

# The node's parameter for each input of the specification (errors name these).
PARAMETER_NAMES = InputNames(
    map='map_file', robot='robot', description='anchor_description_file',
    state_map='anchor_state_variables', medium='medium', pull='pull',
    live_method='live_method', fallback_method='out_of_range_live_method',
    edge_method='edge_live_method', n_twists='live_n_twists', verb='set',
    state_source='capacity_node estimates h, theta_b, theta_l1, theta_l2 ('
                 + '; '.join(f'{k} <- {v}' for k, v in ESTIMATE_SOURCES.items())
                 + ") and feeds a description's state variables from them by name or "
                   'anchor_state_variables')


def node_predictor(map_file: str = '', live_method: str = 'direct',
                   robot: str | None = 'minirquad', medium: str | None = 'm90_sand',
                   n_twists: int = 0, pull: str | None = None,
                   out_of_range_live_method: str = '', anchor_description_file: str = '',
                   anchor_state_variables: str = '', edge_live_method: str = '') -> Predictor:
    """The predictor of capacity_node's parameters (names and meanings as its parameters;
    robot None: a map of any robot, medium None: a map of any medium). ConfigError (one line)
    on any problem.

    live_n_twists 0: DEFAULT_TWISTS (1000) for every surface method, direct included; the
    streaming direct-warm keeps its own (400: its sphere only brackets its cold solves)."""
    if map_file.strip():      # the map's live helpers, '' = none; live_method is unused
        methods = {k: v.strip() for k, v in (('out_of_range_live_method',
                                              out_of_range_live_method),
                                             ('edge_live_method', edge_live_method))
                   if v.strip()}
    else:                     # the live solver; the map's helpers are unused
        methods = {'live_method': live_method}
    for param, method in methods.items():
        if method not in LIVE_METHODS:
            raise ConfigError(f'{param} must be one of {", ".join(LIVE_METHODS)}, '
                              f'got {method!r}')
    if n_twists < 0:
        raise ConfigError(f'live_n_twists must be >= 0 (0 = DEFAULT_TWISTS), got {n_twists}')
    spec = PredictorSpec(
        map=map_file.strip(), robot=robot, description=anchor_description_file.strip() or None,
        state_map=anchor_state_variables if anchor_state_variables.strip() else None,
        medium=medium, pull=pull, live_method=live_method,
        fallback_method=out_of_range_live_method.strip(),
        edge_method=edge_live_method.strip(),
        n_twists=n_twists or {m: DEFAULT_TWISTS for m in PREDICTOR_METHODS})
    try:
        return build(spec, PARAMETER_NAMES)
    except PredictorError as exc:
        raise ConfigError(str(exc)) from exc


def predictor_from_params(p: Mapping[str, Any]) -> Predictor:
    """node_predictor of a whole parameter set, by the node's parameter names (capacity_node
    and tools that feed its estimator read the same ones)."""
    return node_predictor(p['map_file'], p['live_method'], p['robot'], p['medium'],
                          p['live_n_twists'], p['pull'], p['out_of_range_live_method'],
                          anchor_description_file=p['anchor_description_file'],
                          anchor_state_variables=p['anchor_state_variables'],
                          edge_live_method=p['edge_live_method'])


# Two states near the paper's DH anchor (h 34 mm, pitch 5 deg, legs -40 / 30 deg), a tether at
# -20 deg: the first answer runs a live solver cold, the second warm (their kernels differ).
WARM_UP_STATES = (AnchorState(0.034, math.radians(5.0), math.radians(-40.0), math.radians(30.0)),
                  AnchorState(0.034, math.radians(5.3), math.radians(-40.0), math.radians(30.0)))
WARM_UP_PHI = math.radians(-20.0)


def warm_up_predictor(predictor: Predictor, pull: str) -> float:
    """Answer WARM_UP_STATES with the live solvers of `predictor` (a map's edge check and
    out-of-range fallback, else the predictor itself), so numba compiles them now and not in
    the first estimate of a run: ~10-25 s on a machine's first run, well under a second from
    the cache after that (rftgls_core/numba_cache.py). Any answer will do (a described anchor
    may not hold at these states). Returns the seconds taken."""
    t0 = time.perf_counter()
    live = [x for x in (getattr(predictor, 'edge', None), getattr(predictor, 'fallback', None))
            if x is not None] or [predictor]
    for part in live:
        for state in WARM_UP_STATES:
            part.predict(state, WARM_UP_PHI, pull)
    return time.perf_counter() - t0
