"""Point the message wheels' exported CMake targets at this machine's include directories.

The ros-jazzy-*-msgs wheels ship `share/<pkg>/cmake/*__rosidl_generator_pyExport.cmake` files
whose INTERFACE_INCLUDE_DIRECTORIES name the Python and numpy include directories of the
machine the wheels were built on; CMake refuses a target with a non-existent include path, so
no interface package could be built against them. This rewrites every such path that does not
exist to the venv's own (Python: sysconfig; numpy: numpy.get_include()). Idempotent; run by
`make setup` after every install of the lock (docs/design/ros2-from-pip.md,
"Interface packages from pip"). Run with the venv's Python.
"""
from __future__ import annotations

import re
import sys
import sysconfig
from pathlib import Path

_DIRS = re.compile(r'INTERFACE_INCLUDE_DIRECTORIES "([^"]*)"')


def fixed_path(path: str, python_inc: str, numpy_inc: str) -> str:
    """The local replacement of one include directory (unchanged if it exists or is unknown)."""
    if not path or Path(path).exists() or '$' in path:
        return path
    if 'numpy' in path:
        return numpy_inc
    if re.search(r'include/python3\.\d+$', path):
        return python_inc
    return path


def fix_file(f: Path, python_inc: str, numpy_inc: str) -> bool:
    text = f.read_text()

    def repl(m: re.Match) -> str:
        parts = [fixed_path(p, python_inc, numpy_inc) for p in m.group(1).split(';')]
        return f'INTERFACE_INCLUDE_DIRECTORIES "{";".join(parts)}"'

    new = _DIRS.sub(repl, text)
    if new != text:
        f.write_text(new)
        return True
    return False


def main(argv: list[str]) -> int:
    import numpy
    prefix = Path(argv[1] if len(argv) > 1 else sys.prefix)
    python_inc = sysconfig.get_paths()['include']
    numpy_inc = numpy.get_include()
    if not (Path(python_inc) / 'Python.h').exists():
        print(f'fix_rosidl_cmake: no Python.h in {python_inc}: install the Python headers '
              '(python3.11-dev) to build interface packages', file=sys.stderr)
        return 1
    files = sorted((prefix / 'share').glob('*/cmake/*__rosidl_generator_pyExport.cmake'))
    changed = sum(fix_file(f, python_inc, numpy_inc) for f in files)
    print(f'fix_rosidl_cmake: {changed} of {len(files)} exported targets rewritten')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
