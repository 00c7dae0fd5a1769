"""The firmware's host build, run from the tests (one make at a time across pytest workers)."""
from __future__ import annotations

import fcntl
import subprocess
from pathlib import Path

FIRMWARE = Path(__file__).resolve().parents[1] / 'src' / 'minirquad_driver' / 'firmware'
BUILD = FIRMWARE / 'build'


def make(*targets: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """`make -C firmware targets` under a file lock (xdist workers share the build folder)."""
    BUILD.mkdir(exist_ok=True)
    with open(BUILD / '.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return subprocess.run(['make', '-C', str(FIRMWARE), *targets], capture_output=True,
                              text=True, timeout=timeout)


def build_host() -> Path:
    """Build (or bring up to date) the host binaries; returns the build folder."""
    res = make('host')
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return BUILD
