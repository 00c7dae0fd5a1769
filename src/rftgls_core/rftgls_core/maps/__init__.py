"""State-space capacity maps: precomputed capacity and slip twist over the anchor state
(h, thetaB, thetaL1, thetaL2).

    grid.py         MapGrid (axes in SI), default grids (paper prototype, MiniRQuad Table II)
    hdf5.py         file schema, save_map, load_map (validation), MapFileError
    interpolate.py  cell location and multilinear corner weights (pure functions)
    query.py        CapacityMap: load, query (onboard hot path), query_batch
    build.py        build_map: RobotPredictor at every node; local processes or Dask
    accuracy.py     map vs. a reference method at cell centres and random states
    shipped.py      resolve_map: the one resolver of map names and paths; shipped hashes

The query side (grid, hdf5, interpolate, query) imports no RFT code, so the onboard node loads
fast; build/accuracy are imported on first use (the map figures of `rftgls bench` are in
rftgls_core/benchmarks/maps.py).
"""
from __future__ import annotations

from .grid import MapGrid, default_grid
from .hdf5 import (
    SCHEMA,
    SCHEMA_VERSION,
    MapData,
    MapFileError,
    MapIntegrityWarning,
    content_sha256,
    load_map,
    save_map,
)
from .query import BatchAnswer, CapacityMap
from .shipped import SHIPPED, SHIPPED_SHA256, maps_dir, resolve_map, shipped_map_path

_LAZY = {'build_map': 'build', 'BuildSpec': 'build', 'accuracy_report': 'accuracy'}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f'.{_LAZY[name]}', __name__), name)
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


__all__ = ['MapGrid', 'default_grid', 'SCHEMA', 'SCHEMA_VERSION', 'MapData', 'MapFileError',
           'MapIntegrityWarning', 'content_sha256', 'load_map', 'save_map', 'BatchAnswer',
           'CapacityMap', 'build_map', 'BuildSpec',
           'accuracy_report', 'SHIPPED', 'SHIPPED_SHA256', 'maps_dir', 'resolve_map',
           'shipped_map_path']
