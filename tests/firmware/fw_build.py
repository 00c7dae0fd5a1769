"""Where the firmware lives and how its Makefile is run from the tests."""
from __future__ import annotations

import fcntl
import subprocess
from pathlib import Path

FIRMWARE = Path(__file__).resolve().parents[2] / 'src' / 'minirquad_driver' / 'firmware'
BUILD = FIRMWARE / 'build'


def make(*targets: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """`make -C firmware targets`, one at a time across pytest workers (a file lock)."""
    BUILD.mkdir(exist_ok=True)
    with open(BUILD / '.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return subprocess.run(['make', '-C', str(FIRMWARE), *targets], capture_output=True,
                              text=True, timeout=timeout)
