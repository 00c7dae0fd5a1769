"""The simulated MCU's end of a serial line: a pseudo-terminal pair.

The MCU owns the master side; the host opens the slave path (``/dev/pts/N``) exactly like
a USB serial device. Like a udev ``/dev/serial/by-id`` link, an optional fixed symlink
always points at the current slave, and an optional link file holds its path: a simulated
unplug closes the pair and a replug opens a new one with a new /dev/pts number.
"""
from __future__ import annotations

import errno
import os
import tty
from pathlib import Path


class PtyLink:
    def __init__(self, symlink: str | None = None, link_file: str | None = None):
        self.symlink = Path(symlink) if symlink else None
        self.link_file = Path(link_file) if link_file else None
        self.master: int | None = None
        self._slave: int | None = None
        self.slave_path: str | None = None

    def open(self) -> str:
        master, slave = os.openpty()
        # Raw mode at once: a fresh pty echoes and turns \n into \r\n.
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master, self._slave = master, slave
        self.slave_path = os.ttyname(slave)
        if self.symlink:
            tmp = self.symlink.with_name(self.symlink.name + '.tmp')
            tmp.unlink(missing_ok=True)
            tmp.symlink_to(self.slave_path)
            os.replace(tmp, self.symlink)          # atomic: never a missing link
        if self.link_file:
            tmp = self.link_file.with_name(self.link_file.name + '.tmp')
            tmp.write_text(self.slave_path + '\n')
            os.replace(tmp, self.link_file)
        # Keep our own slave fd open until the host has had a chance to open the path: a pty
        # whose slave was never opened reports EIO to the master, and the open fd keeps
        # the device alive. It is closed on ``close``.
        return self.slave_path

    def read(self) -> bytes:
        if self.master is None:
            return b''
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b''
        except OSError as exc:
            if exc.errno == errno.EIO:      # no slave open: nobody is connected
                return b''
            raise

    def write(self, data: bytes) -> int:
        """Write what the line takes now; returns bytes written (a full pty buffer, i.e.
        a host that stopped reading, loses the rest, like a UART)."""
        if self.master is None or not data:
            return 0
        try:
            return os.write(self.master, data)
        except (BlockingIOError, OSError):
            return 0

    def close(self) -> None:
        for fd in (self.master, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.master = self._slave = None

    def remove_links(self) -> None:
        for p in (self.symlink, self.link_file):
            if p is not None:
                try:
                    p.unlink()
                except FileNotFoundError:
                    pass
