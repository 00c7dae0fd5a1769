"""RFT-GLS core: granular resistive force theory, granular limit surfaces, load capacity.

Data flow (see README, design section):
    geometry (meshes) -> robots (posed facets) -> rft (wrench per twist)
    -> surfaces (limit surface, capacity, slip twist) -> maps (HDF5 state-space maps)
    -> sim (quasi-static pull trajectories) -> charts / cli

Everything inside is SI (m, kg, s, N, N m, rad). No ROS import anywhere in this package.
"""
__version__ = '0.1.0'

from . import numba_cache as _numba_cache  # noqa: E402

# before any module decorates a compiled function: the cache must follow the sources
_numba_cache.configure()
