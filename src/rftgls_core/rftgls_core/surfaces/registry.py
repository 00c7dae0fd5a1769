"""The one registry of limit-surface methods: name -> class, imported on first use.

Adding a method: write `surfaces/<name>.py` with a LimitSurface subclass (see base.py for what
it must provide) and add one line below. Imports are lazy so that asking for `direct` does not
load the alpha-shape machinery.
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


def surface_class(method: str) -> type[LimitSurface]:
    """The LimitSurface subclass registered as `method`; ValueError naming the known ones."""
    if method not in _METHODS:
        raise ValueError(f'unknown method {method!r}; known methods: {", ".join(_METHODS)}')
    module, cls = _METHODS[method].split(':')
    return getattr(importlib.import_module(f'{__package__}.{module}'), cls)
