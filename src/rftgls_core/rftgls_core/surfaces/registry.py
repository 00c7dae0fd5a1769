"""The one registry of limit-surface methods: name -> class, imported on first use.

Two kinds of method:
- surface methods, fitted per state: a LimitSurface subclass (`fit(problem)`, then
  `capacity(phi)`); adding one: write `surfaces/<name>.py` (see base.py for what it must
  provide) and add one line to _METHODS.
- streaming methods, kept across the states of a stream: a solver with `solve(problem, phi)`
  and `forget()` that gives the answers of its surface method, warm-started from the previous
  state (`direct-warm`, surfaces/warm.py). The live predictors (predictor/live.py) keep one per
  pull orientation.

Imports are lazy so that asking for `direct` does not load the alpha-shape machinery.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .base import LimitSurface

# method name -> 'module:Class' inside rftgls_core.surfaces
_METHODS = {
    'twist-mesh': 'twist_mesh:TwistMeshSurface',
    'direct': 'direct:DirectSurface',
    'ellipsoid': 'ellipsoid:EllipsoidSurface',
    'alpha': 'alpha_shape:AlphaShapeSurface',
    'brute-force': 'brute_force:BruteForceSurface',
}
METHOD_NAMES: tuple[str, ...] = tuple(_METHODS)
# Methods that serve as references only: seconds per state, for tests and accuracy charts,
# never as a live or lab predictor.
REFERENCE_ONLY: tuple[str, ...] = ('brute-force',)
PREDICTOR_METHODS: tuple[str, ...] = tuple(m for m in METHOD_NAMES if m not in REFERENCE_ONLY)

DEFAULT_METHOD = 'twist-mesh'
DEFAULT_TWISTS = 1000
# direct needs the sphere only to bracket the ray (Newton does the rest): fewer twists; the
# brute-force reference needs a dense one.
DEFAULT_TWISTS_BY_METHOD = {'direct': 400, 'brute-force': 100_000}

# streaming method name -> ('module:Class' inside rftgls_core.surfaces, its surface method)
_STREAMING = {
    'direct-warm': ('warm:WarmDirect', 'direct'),
}
STREAMING_METHODS: tuple[str, ...] = tuple(_STREAMING)
# What a live predictor (capacity_node's live_method, the simulator's ground) may use.
LIVE_METHODS: tuple[str, ...] = STREAMING_METHODS + PREDICTOR_METHODS


def surface_class(method: str) -> type[LimitSurface]:
    """The LimitSurface subclass registered as `method`; ValueError naming the known ones."""
    if method not in _METHODS:
        raise ValueError(f'unknown method {method!r}; known methods: {", ".join(_METHODS)}')
    return _load(_METHODS[method])


def surface_method(method: str) -> str:
    """The surface method whose answers `method` gives: itself, or a streaming method's
    (`direct` for `direct-warm`); ValueError naming the known ones."""
    if method in _STREAMING:
        return _STREAMING[method][1]
    if method not in _METHODS:
        raise ValueError(f'unknown method {method!r}; known methods: '
                         f'{", ".join((*_STREAMING, *_METHODS))}')
    return method


def default_twists(method: str) -> int:
    """The twist count a method samples per state unless told otherwise (a streaming
    method: its surface method's)."""
    return DEFAULT_TWISTS_BY_METHOD.get(surface_method(method), DEFAULT_TWISTS)


def streaming_class(method: str) -> type | None:
    """The solver class of a streaming method (`solve(problem, phi)`, `forget()`), None for
    a surface method."""
    return _load(_STREAMING[method][0]) if method in _STREAMING else None


def _load(target: str):
    module, cls = target.split(':')
    return getattr(importlib.import_module(f'{__package__}.{module}'), cls)
