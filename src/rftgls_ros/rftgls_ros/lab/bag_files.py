"""A bag as untrusted input: its files checked before rosbags opens them, and every failure
of its bytes one BagError (docs/design/safe-io.md).

A pull-test bag is a rosbag2 folder (metadata.yaml and storage files) or one .mcap file. A
FIFO or device among them would block or flood the reader, a huge metadata.yaml or an alias
bomb in it would exhaust memory, so each file is checked (safe_read) before rosbags sees the
bag; what the bag holds is then checked by bag_layout (the lab layout, its metadata).
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path

from rftgls_conventions import one_line
from rftgls_conventions.safe_read import InputFileError, check_regular, parse_yaml, read_text


class BagError(ValueError):
    """A bag that cannot be used as a lab pull test: missing, not rosbag2, truncated or
    corrupt, a topic with an unexpected type, or malformed metadata. One line."""


# Files in a bag folder: metadata.yaml and the storage files (one per split); a recorder
# splitting a long session by size makes tens of them, never thousands.
MAX_BAG_FILES = 1000


def check_bag_files(path) -> None:
    """BagError unless `path` is a bag whose files are all safe to hand to rosbags: a regular
    .mcap file, or a folder of at most MAX_BAG_FILES regular files (safe_read: each within
    its kind's size limit; a FIFO or device is never opened) whose metadata.yaml parses
    within the YAML bounds. Nothing but metadata.yaml is read here."""
    if not os.path.lexists(path):
        raise BagError(f'{path}: no such bag (a rosbag2 folder or .mcap file)')
    try:
        if not Path(path).is_dir():
            check_regular(path, 'bag', 'bag')
            return
        with os.scandir(path) as it:
            entries = [Path(e.path) for e in itertools.islice(it, MAX_BAG_FILES + 1)]
        if len(entries) > MAX_BAG_FILES:
            raise BagError(f'{path}: more than {MAX_BAG_FILES} files; not a pull-test bag')
        for f in entries:
            if f.name == 'metadata.yaml':
                parse_yaml(read_text(f, 'bag_metadata', 'bag metadata'), f)
            else:
                check_regular(f, 'bag', 'bag file')
    except InputFileError as exc:
        raise BagError(str(exc)) from None


def guard_bag_read(path, read):
    """Run read() on a bag, turning every failure of the bag's bytes into one BagError.

    The bag's files are checked first (check_bag_files). rosbags, mcap and CDR decoding raise
    their own types (ReaderError, struct.error, KeyError, IndexError, UnicodeDecodeError,
    ...) on truncated or hostile files; a bag is untrusted input, so all of them mean the
    same thing to the caller.
    """
    check_bag_files(path)
    try:
        return read()
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 -- see docstring
        raise BagError(f'{path}: not a readable rosbag2 pull-test bag '
                       f'({type(exc).__name__}: {one_line(exc)})') from None
