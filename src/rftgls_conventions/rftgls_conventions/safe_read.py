"""Reading files a person names: regular files only, a size limit per kind, bounded parsing.

Every file option of every tool (meshes, media, maps, descriptions and their URDF, xacro and
meshes, bags, CSVs, calibration files, parameter files, video and image frames) reaches its
bytes through this module, so one rule holds everywhere (docs/design/safe-io.md):

- Only a regular file is read. A FIFO would block the reader forever, /dev/zero would fill
  the memory, a directory or socket is a mistake: each is refused with one line before a byte
  is read. The check is made on the open file descriptor (opened non-blocking, so opening a
  FIFO cannot hang), not on the name.
- A size limit per kind (MAX_BYTES) is checked before reading, and reading stops one byte past
  it, so a file that grows while it is read is refused too.
- Documents are parsed with bounds: JSON and YAML nesting at most MAX_NESTING levels, YAML
  aliases at most MAX_ALIASES and the document they expand to at most MAX_NODES nodes (an
  alias bomb expands exponentially; a recursive alias never ends).

Libraries that open files by name themselves (h5py, rosbags, OpenCV) get the name after
`check_regular` has passed. Errors are InputFileError (a ValueError: the command lines print
it in one line and exit 2); the message names the file and never quotes its content.
"""
from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

KIB, MIB, GIB = 1 << 10, 1 << 20, 1 << 30

# Largest file accepted per kind, bytes. Each is far above any real file of its kind and far
# below what would exhaust the robot computer's memory (docs/design/safe-io.md, "Limits").
MAX_BYTES: dict[str, int] = {
    'mesh': 300 * MIB,          # STL: 1e6 triangles in ASCII (~250 bytes each)
    'medium': 1 * MIB,          # medium JSON: five numbers, a covariance, sources (< 10 kB)
    'calibration': 1 * MIB,     # camera intrinsics, pull-test metadata JSON (< 10 kB)
    'description': 1 * MIB,     # anchor description YAML, xacro YAML (< 10 kB)
    'urdf': 16 * MIB,           # URDF or xacro (a large humanoid's URDF is ~1 MB)
    'params': 1 * MIB,          # ROS parameter YAML (a few kB)
    'csv': 64 * MIB,            # penetration traces, frame time stamps (~1e6 rows at most)
    'map': 2 * GIB,             # HDF5 capacity map (shipped ones ~0.2 MB; fine grids ~100 MB)
    'bag': 8 * GIB,             # one rosbag2 storage file (.mcap, .db3) of a pull test
    'bag_metadata': 1 * MIB,    # rosbag2 metadata.yaml (a few kB)
    'video': 8 * GIB,           # camera video of a pull test
    'image': 64 * MIB,          # one camera frame (png, jpg)
    'report': 64 * MIB,         # a cycle report CSV read back by the demo
}
MAX_NESTING = 64        # JSON/YAML levels; the deepest real document here has 4
MAX_ALIASES = 100       # YAML aliases per document
MAX_NODES = 100_000     # YAML nodes after expanding aliases

_KIND_OF_MODE = ((stat.S_ISDIR, 'a directory'), (stat.S_ISFIFO, 'a FIFO'),
                 (stat.S_ISCHR, 'a character device'), (stat.S_ISBLK, 'a block device'),
                 (stat.S_ISSOCK, 'a socket'))


class InputFileError(ValueError):
    """A file that is not read: missing, not a regular file, too large, not text, or a
    document nested or aliased beyond the bounds. One line naming the file."""


def _what(mode: int) -> str:
    for test, name in _KIND_OF_MODE:
        if test(mode):
            return name
    return 'a special file'


def _limit(kind: str) -> int:
    try:
        return MAX_BYTES[kind]
    except KeyError:
        raise ValueError(f'unknown file kind {kind!r}; one of {", ".join(MAX_BYTES)}') from None


def _size_text(n: int) -> str:
    return f'{n / GIB:.3g} GiB' if n >= GIB else f'{n / MIB:.3g} MiB'


def _refuse_stat(path, st: os.stat_result, kind: str, label: str) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise InputFileError(f'{path}: is {_what(st.st_mode)}, not a regular file ({label})')
    limit = _limit(kind)
    if st.st_size > limit:
        raise InputFileError(f'{path}: {st.st_size} bytes, more than the {limit} '
                             f'({_size_text(limit)}) a {label} may have')


def _os_error(path, exc: OSError, label: str) -> InputFileError:
    reason = exc.strerror or type(exc).__name__
    if exc.errno == errno.ENOENT:
        reason = f'no such {label}'
    return InputFileError(f'{path}: cannot read {label} ({reason})')


def check_regular(path: str | os.PathLike, kind: str, label: str | None = None) -> Path:
    """The path of an existing regular file of at most MAX_BYTES[kind] bytes (links are
    followed: the file they name is checked); InputFileError otherwise. For libraries that
    open files by name (h5py, rosbags, OpenCV). label names the kind for people ('mesh')."""
    label = label or kind
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as exc:
        raise _os_error(p, exc, label) from None
    _refuse_stat(p, st, kind, label)
    return p


def check_folder(path: str | os.PathLike, label: str) -> Path:
    """The path of an existing directory (a bag, a folder of frames); InputFileError for
    anything else."""
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as exc:
        raise _os_error(p, exc, label) from None
    if not stat.S_ISDIR(st.st_mode):
        what = 'a file' if stat.S_ISREG(st.st_mode) else _what(st.st_mode)
        raise InputFileError(f'{p}: is {what}, not a folder ({label})')
    return p


def read_bytes(path: str | os.PathLike, kind: str, label: str | None = None) -> bytes:
    """The bytes of a regular file of at most MAX_BYTES[kind] bytes; InputFileError otherwise
    (before any byte is read when the file is not regular or already too large)."""
    label = label or kind
    p = Path(path)
    limit = _limit(kind)
    try:
        # O_NONBLOCK: opening a FIFO for reading without a writer returns at once.
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except OSError as exc:
        raise _os_error(p, exc, label) from None
    try:
        _refuse_stat(p, os.fstat(fd), kind, label)
        chunks, total = [], 0
        while total <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise _os_error(p, exc, label) from None
    finally:
        os.close(fd)
    if total > limit:
        raise InputFileError(f'{p}: grew past the {_size_text(limit)} limit while it was read '
                             f'({label})')
    return b''.join(chunks)


def read_text(path: str | os.PathLike, kind: str, label: str | None = None) -> str:
    """read_bytes decoded as UTF-8 (a byte-order mark dropped); InputFileError for binary."""
    data = read_bytes(path, kind, label)
    try:
        return data.decode('utf-8-sig')
    except UnicodeDecodeError:
        raise InputFileError(f'{path}: not UTF-8 text ({label or kind})') from None


# ------------------------------------------------------------------------------- documents
def json_depth(text: str) -> int:
    """Deepest nesting of arrays and objects in a JSON text (strings skipped), counted
    without recursion so any depth is measured safely."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == '\\':
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in '[{':
            depth += 1
            deepest = max(deepest, depth)
        elif ch in ']}':
            depth -= 1
    return deepest


def parse_json(text: str, source: object) -> object:
    """json.loads with the nesting bound; InputFileError('<source>: ...') on any problem."""
    import json
    if json_depth(text) > MAX_NESTING:
        raise InputFileError(f'{source}: JSON nested deeper than {MAX_NESTING} levels')
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        msg = exc.msg if isinstance(exc, json.JSONDecodeError) else type(exc).__name__
        where = (f' at line {exc.lineno} column {exc.colno}'
                 if isinstance(exc, json.JSONDecodeError) else '')
        raise InputFileError(f'{source}: not JSON ({msg}{where})') from None


def load_json(path: str | os.PathLike, kind: str, label: str | None = None) -> object:
    """A JSON document from a file (read_text, then parse_json)."""
    return parse_json(read_text(path, kind, label), path)


def _bounded_loader(source: object):
    """A yaml SafeLoader class that refuses deep nesting, many aliases, recursive aliases and
    documents that expand past MAX_NODES nodes, before anything is constructed."""
    import yaml

    class BoundedLoader(yaml.SafeLoader):
        def __init__(self, stream):
            super().__init__(stream)
            self._depth = 0
            self._aliases = 0

        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                self._aliases += 1
                if self._aliases > MAX_ALIASES:
                    raise InputFileError(f'{source}: more than {MAX_ALIASES} YAML aliases')
            self._depth += 1
            if self._depth > MAX_NESTING:
                raise InputFileError(f'{source}: YAML nested deeper than {MAX_NESTING} levels')
            try:
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1

        def construct_document(self, node):
            _check_expansion(node, source)
            return super().construct_document(node)

    return BoundedLoader


def _children(node) -> list:
    import yaml
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [n for kv in node.value for n in kv]
    return []


def _check_expansion(root, source: object) -> None:
    """InputFileError when the node graph (aliases share nodes) has a cycle or expands to more
    than MAX_NODES nodes. Iterative post-order walk; each node's expanded size is memoised."""
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            size[key] = 1 + sum(size[id(c)] for c in _children(node))
            if size[key] > MAX_NODES:
                raise InputFileError(f'{source}: YAML expands to more than {MAX_NODES} nodes '
                                     '(aliases)')
            continue
        if key in size:
            continue
        if key in on_path:
            raise InputFileError(f'{source}: YAML alias refers to itself')
        on_path.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in on_path:
                raise InputFileError(f'{source}: YAML alias refers to itself')
            if id(child) not in size:
                stack.append((child, False))


def parse_yaml(text: str | bytes, source: object) -> object:
    """yaml.safe_load with the nesting, alias and expansion bounds; InputFileError on any
    problem (the parser's message is kept to its position, never the offending text)."""
    import yaml
    loader = _bounded_loader(source)(text)
    try:
        return loader.get_single_data()
    except InputFileError:
        raise
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        where = f' at line {mark.line + 1} column {mark.column + 1}' if mark else ''
        raise InputFileError(f'{source}: not YAML ({exc.problem or "syntax error"}{where})') \
            from None
    except (yaml.YAMLError, RecursionError, ValueError, TypeError) as exc:
        raise InputFileError(f'{source}: not YAML ({type(exc).__name__})') from None
    finally:
        loader.dispose()


def load_yaml(path: str | os.PathLike, kind: str, label: str | None = None) -> object:
    """A YAML document from a file (read_text, then parse_yaml)."""
    return parse_yaml(read_text(path, kind, label), path)
