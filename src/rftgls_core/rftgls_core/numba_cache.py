"""Where numba keeps this package's compiled functions: one folder per version of its sources.

numba decides whether a cached function is stale from its own file's time stamp and size
only, but the fused kernels inline functions from other files (rft/kernels.py inlines
rft/kernel_pairs.py; multibody/evaluate.py takes its cubics and friction cap from there).
After an edit to kernel_pairs.py every process went on running the kernels compiled from the
old code, silently: a kernel change measured no faster than the code it replaced, and the
same change in a fresh cache folder 3 % faster. Tests could pass against code that no longer
exists.

So, unless the user chose a folder (NUMBA_CACHE_DIR), the cache goes to a folder named for
a hash of every Python source file of the package: any edit makes a new folder, and a
folder of older code is never read again. Hashing the sources (~1 MB) takes a few
milliseconds at import. Where that folder cannot be written, numba's own default stays.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


def source_hash() -> str:
    """SHA-256 (hex, first 16) over the package's .py files, paths and contents, in order."""
    h = hashlib.sha256()
    for path in sorted(PACKAGE.rglob('*.py')):
        h.update(str(path.relative_to(PACKAGE)).encode())
        h.update(b'\0')
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_folder() -> Path:
    base = os.environ.get('XDG_CACHE_HOME') or str(Path.home() / '.cache')
    return Path(base) / 'rftgls_core' / 'numba' / source_hash()


def configure() -> str | None:
    """Point numba's cache at cache_folder() unless NUMBA_CACHE_DIR is set; the folder used,
    or None when numba's default stays (a folder set by the user, or none writable)."""
    if os.environ.get('NUMBA_CACHE_DIR'):
        return None
    try:
        folder = cache_folder()
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f'.write-test-{os.getpid()}'
        probe.write_bytes(b'')
        probe.unlink()
    except OSError:
        return None
    # the environment for numba when it is imported later (and for worker processes); its
    # config when it already is (read when a cached function is first compiled)
    os.environ['NUMBA_CACHE_DIR'] = str(folder)
    numba = sys.modules.get('numba')
    if numba is not None:
        numba.config.CACHE_DIR = str(folder)
    return str(folder)
