"""The demo launcher end to end: one short cycle, own domain id, report written, exits by itself."""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_demo_one_cycle_exits_and_writes_report(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}
    out = tmp_path / 'demo'
    proc = subprocess.run(
        ['ros2', 'run', 'rftgls_ros', 'behavior_demo', '--out', str(out), '--sleds', '0.4',
         '--cycles', '1', '--param', 'walk_time_s:=1.0', '--param', 'idle_measure_time_s:=0.5',
         '--timeout', '60'],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=90)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    m = re.search(r'ROS_DOMAIN_ID=(\d+), DDS discovery LOCALHOST', text)
    assert m and 1 <= int(m.group(1)) <= 100, text
    assert 'decision (expected pose): SH' in text
    assert '400 g sled -> SH' in text
    assert (out / 'cycle_report.csv').exists() and (out / 'cycle_report.png').exists()
