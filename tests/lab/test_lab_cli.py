"""`rftgls calibrate` (contributed by rftgls_ros through an entry point) writes a medium file
that the core commands accept with --medium."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from rftgls_core.rft.media import load_medium

SAMPLES = Path(__file__).resolve().parents[2] / 'src/rftgls_ros/rftgls_ros/lab/samples'
CLI = [sys.executable, '-m', 'rftgls_core.cli.main']


def test_calibrate_then_use_the_medium_file(tmp_path):
    bags = sorted(str(p) for p in SAMPLES.iterdir() if p.is_dir())
    assert len(bags) >= 2
    medium = tmp_path / 'medium.json'
    out = subprocess.run(CLI + ['calibrate', *bags, '--out', str(medium)], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    data = json.loads(medium.read_text())
    med = load_medium(str(medium))
    assert med.xi_n == pytest.approx(data['xi_n']) and med.mu_surf == pytest.approx(data['mu_surf'])
    cap = subprocess.run(CLI + ['capacity', '--robot', 'prototype', '--h', '0.02', '--theta-b',
                                '0', '--theta-l1', '-40', '--theta-l2', '0', '--pull', 'forward',
                                '--medium', str(medium), '--json'],
                         capture_output=True, text=True, timeout=120)
    assert cap.returncode == 0, cap.stderr
    assert json.loads(cap.stdout)['status'] == 'ok'


def test_bad_medium_file_is_one_line_error(tmp_path):
    bad = tmp_path / 'bad.json'
    bad.write_text('{"name": "x"}')
    out = subprocess.run(CLI + ['capacity', '--h', '0.03', '--theta-b', '0', '--theta-l1', '0',
                                '--theta-l2', '0', '--medium', str(bad)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and 'lacks' in out.stderr and 'Traceback' not in out.stderr
