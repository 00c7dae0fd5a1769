"""The linters the project uses (ruff, configured in the repository's ruff.toml) on this
package's Python files."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1]


def test_ruff():
    proc = subprocess.run([sys.executable, '-m', 'ruff', 'check', str(PKG)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
