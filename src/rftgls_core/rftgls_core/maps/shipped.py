"""Where the shipped maps live: `maps/` at the repository root (or $RFTGLS_MAPS_DIR)."""
from __future__ import annotations

import os
from pathlib import Path

SHIPPED = {'prototype': 'prototype_glass_beads.h5', 'minirquad': 'minirquad_m90_sand.h5'}


def maps_dir() -> Path:
    env = os.environ.get('RFTGLS_MAPS_DIR')
    if env:
        return Path(env)
    # src/rftgls_core/rftgls_core/maps/shipped.py -> repository root (symlinked installs
    # resolve to the source tree).
    return Path(__file__).resolve().parents[4] / 'maps'


def shipped_map_path(robot: str) -> Path:
    """Path of the shipped map of a robot; FileNotFoundError (one clear line) if absent."""
    if robot not in SHIPPED:
        raise ValueError(f'no shipped map for robot {robot!r}; shipped: {", ".join(SHIPPED)}')
    path = maps_dir() / SHIPPED[robot]
    if not path.is_file():
        raise FileNotFoundError(f'shipped map {path} not found (set RFTGLS_MAPS_DIR to the '
                                f'folder that holds {SHIPPED[robot]})')
    return path
