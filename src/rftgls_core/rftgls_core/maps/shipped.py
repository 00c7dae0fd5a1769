"""Where maps are found: the ONE resolver of map names and paths (`resolve_map`).

Search order (docs/design/map-integrity.md):
1. an explicit path, as written (absolute, or relative to the current directory because the
   caller wrote it so), e.g. `--map ./my_map.h5` or `map_file:=/data/m.h5`;
2. the package's installed maps: a robot name ('minirquad'), a shipped file name
   ('minirquad_m90_sand.h5') or the legacy default 'maps/<shipped file>' always mean the copy in
   maps_dir(), whose content must match the hash recorded here (SHIPPED_SHA256);
3. nothing else: the current directory is never searched implicitly, so a file planted there
   cannot stand in for a shipped map.

maps_dir() is `maps/` at the repository root that holds this package (symlinked and editable
installs resolve to the source tree), or $RFTGLS_MAPS_DIR; a plain (copying) `colcon build`
installs the maps to <prefix>/share/rftgls_core/maps, found through the ament index
(AMENT_PREFIX_PATH, read directly: the core imports no ROS package).
"""
from __future__ import annotations

import os
from pathlib import Path

from .errors import MapFileError

SHIPPED = {'prototype': 'prototype_glass_beads.h5', 'minirquad': 'minirquad_m90_sand.h5'}

# Content hashes (hdf5.content_sha256) of the shipped maps, recorded when they were written
# (maps/README.md has the commands). load_map refuses a shipped map that does not match.
SHIPPED_SHA256 = {
    'prototype_glass_beads.h5':
        'b76298ccf4b382c2bed7ba84a9133ea4bcf5bcc2ca594de822f349380e6c67a2',
    'minirquad_m90_sand.h5':
        '39751a97df8c8d65a1ed5ae81e8ddf4bc1826062f5e53a7aea44dd376e6bd684',
}


def maps_dir() -> Path:
    """The folder of the installed (shipped) maps."""
    env = os.environ.get('RFTGLS_MAPS_DIR')
    if env:
        return Path(env)
    # src/rftgls_core/rftgls_core/maps/shipped.py -> repository root.
    repo = Path(__file__).resolve().parents[4] / 'maps'
    if not repo.is_dir():
        for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
            index = Path(prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
            share = Path(prefix) / 'share' / 'rftgls_core' / 'maps'
            if prefix and (index / 'rftgls_core').is_file() and share.is_dir():
                return share
    return repo


def _shipped_name(spec: str) -> str | None:
    """The shipped file a spec names (robot, file name, 'maps/<file>'), or None."""
    if spec in SHIPPED:
        return SHIPPED[spec]
    p = Path(spec)
    if p.name in SHIPPED.values() and p.parent in (Path('.'), Path('maps')) \
            and not spec.startswith(('./', '.' + os.sep)):
        return p.name
    return None


def resolve_map(spec: str | os.PathLike | None = None, robot: str | None = None) -> Path:
    """Path of the map a caller means (see the module doc for the order). MapFileError (one
    line) when there is none.

    spec: explicit path, shipped file name or robot name; None or '' -> the shipped map of
    `robot`. robot: used only when spec is empty.
    """
    text = '' if spec is None else os.fspath(spec).strip()
    if not text:
        if not robot:
            raise MapFileError('no map given and no robot to pick a shipped map for')
        key = robot.strip().lower()
        if key not in SHIPPED:
            raise MapFileError(f'no shipped map for robot {robot!r}; shipped: '
                               f'{", ".join(SHIPPED)}')
        text = key
    name = _shipped_name(text)
    if name is not None:
        path = maps_dir() / name
        if not path.is_file():
            raise MapFileError(f'shipped map {path} not found (set RFTGLS_MAPS_DIR to the '
                               f'folder that holds {name})')
        return path
    return regular_map_file(Path(text).expanduser())


def regular_map_file(path: str | os.PathLike) -> Path:
    """path when it is a regular file within the map size limit (safe_read); MapFileError
    (one line) otherwise: a FIFO or device would hang or flood the HDF5 reader."""
    from rftgls_conventions.safe_read import InputFileError, check_regular
    try:
        return check_regular(path, 'map', 'map file')
    except InputFileError as exc:
        raise MapFileError(str(exc)) from None


def shipped_map_path(robot: str) -> Path:
    """The installed map of a robot: `resolve_map(None, robot)`."""
    return resolve_map(None, robot)
