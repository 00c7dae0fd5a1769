"""Serial transport with automatic reconnect, on pyserial.

A reader thread owns the port: it opens it (``serial_for_url``, so ``loop://`` and
``socket://`` URLs work as well as device paths), hands every chunk it reads to
``on_bytes(data, host_time)``, and on any error (USB unplug: pyserial raises
SerialException) or after ``silence_timeout`` without a byte it closes the port, reports
the state change, and retries the open every ``reconnect_period`` seconds. The node never
has to restart. A port that cannot be opened (missing, not a tty, no permission) is
reported through ``on_open_error(reason)`` once per failure episode, again only when the
reason changes or after the port was open in between; every attempt is counted.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import serial


@dataclass
class TransportStats:
    connects: int = 0          # successful opens (the first one included)
    disconnects: int = 0       # port lost after having been open
    open_failures: int = 0
    silence_reconnects: int = 0
    write_errors: int = 0
    last_open_error: str | None = None   # reason of the latest failed open, None once open
    bytes_in: int = 0
    bytes_out: int = 0

    @property
    def reconnects(self) -> int:
        return max(0, self.connects - 1)


class SerialTransport:
    def __init__(self, url: str, baudrate: int,
                 on_bytes: Callable[[bytes, float], None],
                 on_state: Callable[[bool], None] = lambda connected: None,
                 read_timeout: float = 0.02, reconnect_period: float = 0.25,
                 silence_timeout: float = 1.0, opener=serial.serial_for_url,
                 on_open_error: Callable[[str], None] = lambda reason: None):
        self.url = url
        self.baudrate = baudrate
        self.on_bytes = on_bytes
        self.on_state = on_state
        self.read_timeout = read_timeout
        self.reconnect_period = reconnect_period
        self.silence_timeout = silence_timeout
        self.opener = opener
        self.on_open_error = on_open_error
        self._reported: str | None = None      # reason already reported in this episode
        self.stats = TransportStats()
        self._port = None
        self._lock = threading.Lock()          # guards _port for writers
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def connected(self) -> bool:
        return self._port is not None

    def start(self) -> None:
        """Start the reader thread (again after stop(): a lifecycle node reconfigures)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='serial-reader', daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread:
            self._thread.join(timeout=2.0)
        self._close()

    def write(self, data: bytes) -> bool:
        with self._lock:
            port = self._port
            if port is None:
                return False
            try:
                port.write(data)
                self.stats.bytes_out += len(data)
                return True
            except (serial.SerialException, OSError, ValueError):
                # A timeout or a vanished device; the reader notices and reconnects.
                self.stats.write_errors += 1
                return False

    def _open(self) -> bool:
        try:
            port = self.opener(self.url, baudrate=self.baudrate, timeout=self.read_timeout,
                               write_timeout=0.1)
        except (serial.SerialException, OSError, ValueError) as exc:
            self.stats.open_failures += 1
            reason = ' '.join(f'{type(exc).__name__}: {exc}'.split())   # one line
            self.stats.last_open_error = reason
            if reason != self._reported:
                self._reported = reason
                self.on_open_error(reason)
            return False
        self._reported = self.stats.last_open_error = None
        with self._lock:
            self._port = port
        self.stats.connects += 1
        self.on_state(True)
        return True

    def _close(self) -> None:
        with self._lock:
            port, self._port = self._port, None
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._port is None:
                if not self._open():
                    self._stop.wait(self.reconnect_period)
                    continue
                last_rx = time.monotonic()
            port = self._port
            try:
                data = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError):
                data = None
            now = time.monotonic()
            if data:
                last_rx = now
                self.stats.bytes_in += len(data)
                self.on_bytes(data, time.time())
                continue
            lost = data is None
            if not lost and now - last_rx > self.silence_timeout:
                self.stats.silence_reconnects += 1
                lost = True
            if lost:
                self._close()
                self.stats.disconnects += 1
                self.on_state(False)
                self._stop.wait(self.reconnect_period)
