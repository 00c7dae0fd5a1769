"""Imported by the fork server of local build workers (`build.WORKER_MODULES`), and by nothing
else: importing it runs one state of the prototype map, so the compiled kernels a build calls
(RFT, mesh loops, solvers' numba helpers) and the twist spheres' connectivity are loaded in the
server once, and every worker forked from it starts with them (measured: ~0.2 s of CPU at a
worker's first state otherwise). Warming is optional: any failure leaves a cold server.
"""
from __future__ import annotations

import sys


def warm() -> None:
    """One state of the prototype robot's map in glass beads, its answers discarded.

    Every kernel call serial: asking numba for its thread count would start its thread pool,
    and the server is to stay a single-threaded process to fork from."""
    from ..rft import kernels
    from ..rft.media import get_medium
    from .build import BuildSpec, solve_chunk
    from .grid import prototype_grid
    before = kernels.PARALLEL_MIN_PAIRS
    kernels.PARALLEL_MIN_PAIRS = sys.maxsize    # use_parallel: False before asking numba
    try:
        solve_chunk(BuildSpec('prototype', get_medium('glass_beads')), prototype_grid(), [0])
    finally:
        kernels.PARALLEL_MIN_PAIRS = before


try:
    warm()
except Exception:  # noqa: BLE001 - a failed warm-up costs the workers time, nothing else
    pass
