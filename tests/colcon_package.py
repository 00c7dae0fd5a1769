"""What `colcon test --packages-select PKG` runs for a Python package of this repository: the
repository's unit tests of that package (in tests/, where `make test` runs them with the rest)
and the linters `make lint` runs on it. Each package's test/test_PKG.py names its unit tests
and takes its checks from here."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


# The inner run's limit, and the outer test's (pytest.ini's 120 s per test would end the
# outer test first and lose what the inner run printed).
INNER_TIMEOUT_S = 300
OUTER_TIMEOUT_S = INNER_TIMEOUT_S + 60


def _text(out: str | bytes | None) -> str:
    return out.decode(errors='replace') if isinstance(out, bytes) else (out or '')


def _run(*cmd: str) -> subprocess.CompletedProcess:
    """cmd in the repository; a run past INNER_TIMEOUT_S fails with the tail of what it
    printed (a stuck test's stacks, from pytest.ini's faulthandler_timeout)."""
    # colcon's pytest options (junit file, prefix) are for the outer run only.
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'}
    try:
        return subprocess.run([sys.executable, '-m', *cmd], cwd=REPO, env=env,
                              capture_output=True, text=True, timeout=INNER_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f'{" ".join(cmd[:2])} ran past {INNER_TIMEOUT_S} s:\n'
                             + _text(exc.stdout)[-3000:] + _text(exc.stderr)[-6000:]) from None


def package_checks(package: str, unit_tests: list[str]):
    """(unit_tests, ruff, mypy): argument-free test functions for one package (pytest
    collects them under the names a package's test file gives them)."""
    pkg = REPO / 'src' / package

    @pytest.mark.timeout(OUTER_TIMEOUT_S)
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
