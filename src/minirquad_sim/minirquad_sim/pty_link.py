"""The simulated MCU's end of a serial line: a pseudo-terminal pair.

The MCU owns the master side; the host opens the slave path (``/dev/pts/N``) exactly like
a USB serial device. Like a udev ``/dev/serial/by-id`` link, an optional fixed symlink
always points at the current slave, and an optional link file holds its path: a simulated
unplug closes the pair and a replug opens a new one with a new /dev/pts number.

Both paths usually live in a shared directory such as /tmp, so they are written the way a
careful daemon writes there: the new content is created under a fresh random name in the
same directory (O_EXCL for the file, a new symlink for the link: neither can follow
anything), then renamed over the target, and rename never follows a link at the target.
Before that, whatever already sits at a target must be ours: the link or file this run
made, or, for a leftover of an earlier run, a symlink (for ``symlink``) or a regular file
(for ``link_file``) owned by this user. Anything else (a planted symlink where the file
goes, someone else's file, a directory) is refused with ``LinkPathError``.
"""
from __future__ import annotations

import errno
import os
import secrets
import stat
import tempfile
import tty
from pathlib import Path


class LinkPathError(RuntimeError):
    """A link path is occupied by something this process must not replace."""


def _check_target(path: Path, want_link: bool, made: tuple[int, int, int] | None) -> None:
    """Raise LinkPathError unless ``path`` is absent or safe to rename over."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if made is not None and (st.st_dev, st.st_ino, stat.S_IFMT(st.st_mode)) == made:
        return
    kind = 'symlink' if stat.S_ISLNK(st.st_mode) else (
        'regular file' if stat.S_ISREG(st.st_mode) else 'special file or directory')
    ok_kind = stat.S_ISLNK(st.st_mode) if want_link else stat.S_ISREG(st.st_mode)
    if not ok_kind or st.st_uid != os.getuid():
        raise LinkPathError(f'refusing to replace {path}: a {kind} owned by uid '
                            f'{st.st_uid} that this simulator did not create')


def _publish_symlink(path: Path, target: str) -> None:
    for _ in range(16):
        tmp = path.with_name(f'.{path.name}.{secrets.token_hex(8)}')
        try:
            os.symlink(target, tmp)
        except FileExistsError:
            continue
        os.replace(tmp, path)          # atomic: never a missing link, never follows
        return
    raise LinkPathError(f'cannot create a temporary link next to {path}')


def _publish_file(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f'.{path.name}.')   # O_EXCL
    try:
        with os.fdopen(fd, 'w') as f:
            f.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _ident(path: Path) -> tuple[int, int, int]:
    # The kind too: a freed inode number is soon reused, e.g. by a link planted in its place.
    st = os.lstat(path)
    return st.st_dev, st.st_ino, stat.S_IFMT(st.st_mode)


class PtyLink:
    def __init__(self, symlink: str | None = None, link_file: str | None = None):
        self.symlink = Path(symlink) if symlink else None
        self.link_file = Path(link_file) if link_file else None
        self.master: int | None = None
        self._slave: int | None = None
        self.slave_path: str | None = None
        self._made: dict[Path, tuple[int, int, int]] = {}   # path -> _ident we created

    def open(self) -> str:
        """Open a new pty pair and point the link paths at it; LinkPathError (nothing
        opened) if a link path holds something this process must not replace."""
        if self.symlink:
            _check_target(self.symlink, True, self._made.get(self.symlink))
        if self.link_file:
            _check_target(self.link_file, False, self._made.get(self.link_file))
        master, slave = os.openpty()
        # Raw mode at once: a fresh pty echoes and turns \n into \r\n.
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master, self._slave = master, slave
        self.slave_path = os.ttyname(slave)
        if self.symlink:
            _publish_symlink(self.symlink, self.slave_path)
            self._made[self.symlink] = _ident(self.symlink)
        if self.link_file:
            _publish_file(self.link_file, self.slave_path + '\n')
            self._made[self.link_file] = _ident(self.link_file)
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
        """Remove the link paths, but only what this run created (still in place)."""
        for p, ident in list(self._made.items()):
            try:
                if _ident(p) == ident:
                    p.unlink()
            except FileNotFoundError:
                pass
        self._made.clear()
