"""`make test` collects its real-time phases from the folders the Makefile names
(REALTIME_TESTS): a real-time test anywhere else would never run there. pytest's own
collection, not a text search, says where the real-time tests are."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def realtime_folders() -> list[str]:
    m = re.search(r'^REALTIME_TESTS := (.+)$', (REPO / 'Makefile').read_text(), re.M)
    assert m, 'the Makefile names no REALTIME_TESTS'
    return m.group(1).split()


def test_every_real_time_test_is_in_a_folder_make_test_collects_them_from():
    folders = realtime_folders()
    assert folders and all((REPO / f).is_dir() for f in folders), folders
    env = {k: v for k, v in os.environ.items() if not k.startswith('PYTEST_XDIST')}
    out = subprocess.run([sys.executable, '-m', 'pytest', 'tests', '-m', 'realtime or alone',
                          '--collect-only', '-q'], cwd=REPO, env=env, capture_output=True,
                         text=True, timeout=100)
    assert out.returncode == 0, out.stdout + out.stderr
    ids = [line for line in out.stdout.splitlines() if '::' in line]
    assert len(ids) >= 20, out.stdout     # the stacks and the stop campaign are there
    outside = [i for i in ids if not any(i.startswith(f + '/') for f in folders)]
    assert not outside, f'real-time tests outside {folders}: {outside}'
