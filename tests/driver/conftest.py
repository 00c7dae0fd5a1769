"""Driver test helpers: start the simulated MCU on a pty, run the bridge node in-process."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))   # strategies.py


# The compiled firmware is the MCU a robot runs: `make test` drives it; the Python reference MCU
# repeats every test in `make test-campaign`.
@pytest.fixture(params=['firmware', pytest.param('python', marks=pytest.mark.campaign)])
def sim(request, spawn, python_exe, tmp_path):
    """Start ``minirquad_sim`` (as ``python -m``) with extra args; returns a handle with the
    symlink path, the record file and a reader for its telemetry records. Every test that
    uses it runs twice: against the Python reference MCU and against the compiled firmware
    (``--mcu firmware``: fw_sitl on the same pty, the Python plant behind it)."""
    mcu = request.param
    if mcu == 'firmware':
        request.getfixturevalue('firmware_build')

    class Sim:
        def start(self, *args: str):
            self.link = tmp_path / 'tty'
            self.path_file = tmp_path / 'tty.path'
            self.record = tmp_path / 'record.jsonl'
            self.proc = spawn([python_exe, '-m', 'minirquad_sim.main',
                               '--symlink', str(self.link), '--link-file', str(self.path_file),
                               '--record', str(self.record), '--mcu', mcu, *args])
            deadline = time.monotonic() + 30.0   # the live ground warms up first (loaded host)
            while not self.path_file.exists():
                assert self.proc.poll() is None, 'simulator exited'
                assert time.monotonic() < deadline, 'simulator did not open its pty'
                time.sleep(0.02)
            return self

        mcu_kind = mcu

        def records(self) -> list[dict]:
            return [json.loads(line) for line in self.record.read_text().splitlines()
                    if line.strip()]

    return Sim()


@pytest.fixture
def harness(ros_context):
    """make(port, **params) -> a bridge_harness.Harness, closed after the test."""
    from bridge_harness import Harness

    made = []

    def make(port, **params):
        h = Harness(ros_context, port, **params)
        made.append(h)
        return h

    yield make
    for h in made:
        h.close()
