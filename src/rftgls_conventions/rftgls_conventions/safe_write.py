"""Writing outputs: a fresh name in the target's folder, fsync, rename over the target.

Every file the project writes (CSV, JSON, PNG, HDF5 maps, bags, reports, logs) goes through
this module (docs/design/safe-io.md, "Writing"):

- `atomic_write(target)` hands the writer a path inside a private folder (mode 0700, made
  fresh by mkdtemp) next to the target. When the writer is done, the new file is fsynced and
  renamed over the target. rename(2) replaces the directory entry itself: a symlink planted at
  the target is replaced by the new file and the file it pointed to is left unchanged; a
  reader sees the old file or the new one, never half of one; a failed writer leaves the
  target as it was.
- `open_fresh(path)` is for streams written while a program runs (node logs): whatever is at
  the path (a file or a symlink, never followed) is removed and a new file is created with
  O_CREAT | O_EXCL | O_NOFOLLOW.
- `output_file` and `output_folder` check what an --out option means before any work starts:
  a file option naming a folder is refused, not turned into `FOLDER.png` beside it; a folder
  option naming a file is refused. A folder that cannot be written is found before the
  computation, not after it.

Only the last component of a path is protected: the folders leading to it are the user's
(an output folder that is itself a symlink to a data disk is followed, as any folder is).
Errors are OutputError (a ValueError: one line, exit 2 on the command lines).
"""
from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO


class OutputError(ValueError):
    """An output that cannot be written where the option says. One line naming the path."""


def _nearest_existing(p: Path) -> Path:
    p = p.absolute()
    while not os.path.lexists(p) and p != p.parent:
        p = p.parent
    return p


def _check_writable_folder(folder: Path, prefix: str) -> None:
    """The folder exists and is writable, or can be made: its nearest existing ancestor is a
    writable folder. OutputError otherwise."""
    base = _nearest_existing(folder)
    if not base.is_dir():
        raise OutputError(f'{prefix}: {base} is not a folder')
    try:   # the real test (permission bits say little to root, or on /proc or a full disk)
        os.rmdir(tempfile.mkdtemp(prefix='.write-probe-', dir=base))
    except OSError as exc:
        raise OutputError(f'{prefix}: cannot write in {base} '
                          f'({exc.strerror or type(exc).__name__})') from None


def output_file(path: str | os.PathLike, label: str = '--out',
                suffixes: tuple[str, ...] = ()) -> Path:
    """The file an output option names, checked: not empty, not a folder (an existing one or
    a name ending in '/'), with one of `suffixes` (lower case, e.g. ('.png',)) when given, in
    a folder that exists or can be made and is writable. OutputError otherwise."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f'{label}: empty file name')
    p = Path(text)
    if text.endswith(('/', os.sep)) or (p.is_dir() and not p.is_symlink()):
        example = p / ('out' + (suffixes[0] if suffixes else ''))
        raise OutputError(f'{label} {text}: is a folder; give a file name (e.g. {example})')
    if suffixes and p.suffix.lower() not in suffixes:
        raise OutputError(f'{label} {text}: must end with {" or ".join(suffixes)}')
    _check_writable_folder(p.parent, f'{label} {text}')
    return p


def output_folder(path: str | os.PathLike, label: str = '--out') -> Path:
    """The folder an output option names, checked: an existing file there is refused (never
    written over or beside), and the folder must exist or be makeable and writable. Nothing
    is made here (a run refused later leaves no folder behind); atomic_write makes it when
    the first output is written. OutputError otherwise."""
    text = os.fspath(path)
    if not text.strip():
        raise OutputError(f'{label}: empty folder name')
    p = Path(text)
    if os.path.lexists(p) and not p.is_dir():
        raise OutputError(f'{label} {text}: exists and is not a folder; give a folder')
    _check_writable_folder(p, f'{label} {text}')
    return p


def _fsync_path(p: Path) -> None:
    fd = os.open(p, os.O_RDONLY | getattr(os, 'O_DIRECTORY', 0) * p.is_dir())
    try:
        os.fsync(fd)
    except OSError:   # some file systems cannot fsync a directory; the data is still written
        pass
    finally:
        os.close(fd)


def _fsync_tree(p: Path) -> None:
    if p.is_dir():
        for child in sorted(p.rglob('*')):
            if child.is_file() and not child.is_symlink():
                _fsync_path(child)
    _fsync_path(p)


@contextmanager
def atomic_write(target: str | os.PathLike, folder: bool = False) -> Iterator[Path]:
    """Yield a fresh path to write to (same file name, inside a new private folder next to
    `target`); on success, fsync it and rename it over `target`.

    folder=False: the writer makes a file. An existing file or symlink at `target` is
    replaced (the rename is atomic); an existing folder is refused.
    folder=True: the writer makes a folder (a rosbag2 bag). A symlink at `target` is removed
    and the folder renamed in its place; an existing folder or file is refused.
    On any exception the target is left as it was and the temporary folder is removed.
    """
    target = Path(target)
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f'{target}: cannot make its folder ({exc.strerror or exc})') from None
    if os.path.lexists(target) and not target.is_symlink():
        if folder:
            raise OutputError(f'{target}: already exists; give a new name')
        if target.is_dir():
            raise OutputError(f'{target}: is a folder; give a file name')
    try:
        work = Path(tempfile.mkdtemp(prefix=f'.{target.name}.', suffix='.tmp', dir=parent))
    except OSError as exc:
        raise OutputError(f'{target}: cannot write in {parent} ({exc.strerror or exc})') \
            from None
    tmp = work / target.name
    try:
        yield tmp
        if tmp.is_symlink() or not (tmp.is_dir() if folder else tmp.is_file()):
            raise OutputError(f'{target}: the writer left no {"folder" if folder else "file"}')
        _fsync_tree(tmp)
        if folder and target.is_symlink():
            os.unlink(target)
        os.replace(tmp, target)
        _fsync_path(parent)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def write_bytes(target: str | os.PathLike, data: bytes) -> Path:
    """Write `data` to `target` atomically (atomic_write); returns the target path."""
    with atomic_write(target) as tmp:
        with open(tmp, 'xb') as fh:
            fh.write(data)
    return Path(target)


def write_text(target: str | os.PathLike, text: str, encoding: str = 'utf-8') -> Path:
    """Write `text` to `target` atomically (atomic_write); returns the target path."""
    return write_bytes(target, text.encode(encoding))


def open_fresh(path: str | os.PathLike, mode: str = 'w', **kwargs) -> IO:
    """A new file at `path` for a stream written while a program runs (a log): an existing
    file or symlink there is removed first (a link is never followed), an existing folder
    refused. mode: 'w', 'wb', 'a' or 'ab' (the file is new either way)."""
    if mode not in ('w', 'wb', 'a', 'ab'):
        raise ValueError(f'open_fresh writes new files; mode {mode!r}')
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(p):
            if p.is_dir() and not p.is_symlink():
                raise OutputError(f'{p}: is a folder; give a file name')
            os.unlink(p)
        flags = (os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
                 | getattr(os, 'O_CLOEXEC', 0) | (os.O_APPEND if 'a' in mode else 0))
        fd = os.open(p, flags, 0o666)
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(f'{p}: cannot write ({exc.strerror or exc})') from None
    return os.fdopen(fd, mode, **kwargs)
