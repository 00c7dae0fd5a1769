"""Firmware test helpers: the host build (g++, AddressSanitizer + UBSan), made once per run."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))                   # fw_build.py
sys.path.insert(0, str(Path(__file__).parents[1] / 'driver'))    # strategies.py

from fw_build import BUILD, make  # noqa: E402


@pytest.fixture(scope='session')
def firmware_build() -> Path:
    """The build folder with the host binaries (built or brought up to date here)."""
    res = make('host')
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return BUILD
