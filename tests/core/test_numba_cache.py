"""numba's cache follows the package's sources (rftgls_core/numba_cache.py): numba re-checks a
cached function against its own file only, and the fused kernels inline functions from
another file, so an edit there ran the old compiled kernels until the folder was keyed by
every source."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from rftgls_core import numba_cache


def _copy(tmp_path: Path) -> Path:
    dst = tmp_path / 'rftgls_core'
    shutil.copytree(numba_cache.PACKAGE, dst, ignore=shutil.ignore_patterns('__pycache__'))
    return dst


def test_an_edit_to_an_inlined_kernel_file_moves_the_cache(tmp_path, monkeypatch):
    copy = _copy(tmp_path)
    monkeypatch.setattr(numba_cache, 'PACKAGE', copy)
    before = numba_cache.source_hash()
    assert before == numba_cache.source_hash()           # the same sources, the same folder
    pairs = copy / 'rft' / 'kernel_pairs.py'
    # kernel_pairs.py is inlined into rft/kernels.py: kernels.py's own stamp is unchanged
    pairs.write_text(pairs.read_text() + '\n# an edit\n')
    assert numba_cache.source_hash() != before


def test_the_cache_folder_is_the_package_hash_unless_the_user_chose_one(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != 'NUMBA_CACHE_DIR'}
    env['XDG_CACHE_HOME'] = str(tmp_path / 'cache')
    code = 'import os, rftgls_core, numba; print(os.environ["NUMBA_CACHE_DIR"]); ' \
           'print(numba.config.CACHE_DIR)'
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    expect = str(tmp_path / 'cache' / 'rftgls_core' / 'numba' / numba_cache.source_hash())
    assert out == [expect, expect]
    # numba imported first: its config is pointed there too
    code = 'import numba, rftgls_core; print(numba.config.CACHE_DIR)'
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [expect]
    # a folder the user set wins
    env['NUMBA_CACHE_DIR'] = str(tmp_path / 'mine')
    code = 'import rftgls_core, numba; print(numba.config.CACHE_DIR)'
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [str(tmp_path / 'mine')]


def test_an_unwritable_cache_location_leaves_numbas_default(tmp_path, monkeypatch):
    blocked = tmp_path / 'file'
    blocked.write_text('not a folder')
    monkeypatch.delenv('NUMBA_CACHE_DIR', raising=False)
    monkeypatch.setenv('XDG_CACHE_HOME', str(blocked))     # mkdir under a file fails
    assert numba_cache.configure() is None
    assert 'NUMBA_CACHE_DIR' not in os.environ
