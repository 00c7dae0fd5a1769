"""`colcon test --packages-select rftgls_ros`: the repository's unit tests of this package
(tests/ at the repository root, where `make test` runs them with the rest), then the linters
`make lint` runs on it."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
PACKAGE = REPO / 'src' / 'rftgls_ros'
UNIT_TESTS = ['tests/ros/test_tf_tree.py',
              'tests/ros/test_capacity_estimator.py',
              'tests/ros/test_launch_files.py',
              'tests/ros/test_rviz_config.py',
              'tests/stack/test_tug_action_unit.py']


def _run(*cmd: str) -> subprocess.CompletedProcess:
    # colcon's pytest options (junit file, prefix) are for the outer run only.
    env = {k: v for k, v in os.environ.items() if k != 'PYTEST_ADDOPTS'}
    return subprocess.run([sys.executable, '-m', *cmd], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=900)


def test_unit_tests_of_the_package():
    missing = [t for t in UNIT_TESTS if not (REPO / t).is_file()]
    assert not missing, f'the repository checkout is incomplete: {missing}'
    proc = _run('pytest', '-q', *UNIT_TESTS)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]


def test_ruff():
    proc = _run('ruff', 'check', str(PACKAGE))
    assert proc.returncode == 0, proc.stdout + proc.stderr
