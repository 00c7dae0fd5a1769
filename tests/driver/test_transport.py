"""SerialTransport: a port that cannot be opened is reported once per episode and retried.
The opener is the hardware boundary, so it is scripted here; the
end-to-end test with a real missing path and a real non-tty file is in test_fault_campaign.
"""
from __future__ import annotations

import threading
import time

import serial

from minirquad_driver.transport import SerialTransport


class _Port:
    """Enough of a pyserial port: nothing to read until closed."""

    in_waiting = 0

    def __init__(self):
        self.closed = False

    def read(self, n):
        time.sleep(0.005)
        if self.closed:
            raise serial.SerialException('device reports readiness to read but returned '
                                         'no data')
        return b''

    def write(self, data):
        return len(data)

    def close(self):
        self.closed = True


def _wait(cond, timeout=3.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


def test_open_failure_is_reported_once_per_episode_and_retried():
    script = {'error': FileNotFoundError(2, 'No such file or directory')}
    port = {}
    reports: list[str] = []
    states: list[bool] = []
    lock = threading.Lock()

    def opener(url, **kw):
        with lock:
            if script['error'] is not None:
                raise script['error']
            port['p'] = _Port()
            return port['p']

    t = SerialTransport('/dev/ttyNOPE', 115200, lambda d, h: None, states.append,
                        reconnect_period=0.01, silence_timeout=60.0, opener=opener,
                        on_open_error=reports.append)
    t.start()
    try:
        assert _wait(lambda: t.stats.open_failures >= 10)
        assert len(reports) == 1 and 'FileNotFoundError' in reports[0]
        assert t.stats.last_open_error == reports[0]
        # Another reason (permissions) is a new report, once.
        with lock:
            script['error'] = PermissionError(13, 'Permission denied')
        n = t.stats.open_failures
        assert _wait(lambda: t.stats.open_failures >= n + 10)
        assert len(reports) == 2 and 'PermissionError' in reports[1]
        # The port appears: opened, error cleared.
        with lock:
            script['error'] = None
        assert _wait(lambda: states == [True])
        assert t.stats.last_open_error is None
        # Unplugged and gone again: a new episode, reported again even with the first reason.
        with lock:
            script['error'] = FileNotFoundError(2, 'No such file or directory')
        port['p'].close()
        assert _wait(lambda: len(reports) == 3)
        assert 'FileNotFoundError' in reports[2] and states == [True, False]
    finally:
        t.stop()
