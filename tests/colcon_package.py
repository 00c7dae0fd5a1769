"""What `colcon test --packages-select PKG` runs for a Python package of this repository: the
repository's unit tests of that package (in tests/, where `make test` runs them with the rest)
and the linters `make lint` runs on it. Each package's test/test_PKG.py names its unit tests
and takes its checks from here."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _run(*cmd: str) -> subprocess.CompletedProcess:
    # colcon's pytest options (junit file, prefix) are for the outer run only.
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'}
    return subprocess.run([sys.executable, '-m', *cmd], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=900)


def package_checks(package: str, unit_tests: list[str]):
    """(unit_tests, ruff, mypy): argument-free test functions for one package (pytest
    collects them under the names a package's test file gives them)."""
    pkg = REPO / 'src' / package

    def run_unit_tests() -> None:
        missing = [t for t in unit_tests if not (REPO / t).is_file()]
        assert not missing, f'the repository checkout is incomplete: {missing}'
        proc = _run('pytest', '-q', *unit_tests)
        assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]

    def ruff() -> None:
        proc = _run('ruff', 'check', str(pkg))
        assert proc.returncode == 0, proc.stdout + proc.stderr

    def mypy() -> None:
        proc = _run('mypy', str(pkg / package))
        assert proc.returncode == 0, proc.stdout + proc.stderr
    return run_unit_tests, ruff, mypy
