"""The simulator's link paths are written safely in a shared directory.

An attacker who can write to the directory (like /tmp) plants a symlink where the link
file or the fixed symlink goes, or at the old predictable temporary name, hoping the
simulator writes through it into a file of theirs choosing. These tests plant such links
and check that the victim file is never touched and that the simulator either refuses
with one line (exit 2) or works around the plant without following it.
"""
from __future__ import annotations

import os
import subprocess

import pytest

from minirquad_sim.pty_link import LinkPathError, PtyLink

VICTIM_TEXT = 'precious\n'


@pytest.fixture
def victim(tmp_path):
    p = tmp_path / 'victim.txt'
    p.write_text(VICTIM_TEXT)
    return p


def _run_sim(python_exe, tmp_path, *args, timeout=20.0):
    return subprocess.run([python_exe, '-m', 'minirquad_sim.main', *args,
                           '--duration', '0.3'],
                          capture_output=True, text=True, timeout=timeout, cwd=tmp_path)


def test_planted_symlink_at_link_file_is_refused_in_one_line(python_exe, tmp_path, victim):
    link_file = tmp_path / 'tty.path'
    link_file.symlink_to(victim)
    r = _run_sim(python_exe, tmp_path, '--link-file', str(link_file))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and 'Traceback' not in r.stderr
    assert victim.read_text() == VICTIM_TEXT
    assert os.path.islink(link_file) and os.readlink(link_file) == str(victim)


def test_planted_link_at_old_temporary_name_is_never_followed(python_exe, tmp_path, victim):
    # The simulator used to write "<link-file>.tmp" and "<symlink>.tmp" with plain opens.
    link_file, link = tmp_path / 'tty.path', tmp_path / 'tty'
    (tmp_path / 'tty.path.tmp').symlink_to(victim)
    (tmp_path / 'tty.tmp').symlink_to(victim)
    r = _run_sim(python_exe, tmp_path, '--link-file', str(link_file), '--symlink', str(link))
    assert r.returncode == 0, r.stderr
    assert victim.read_text() == VICTIM_TEXT
    slave = r.stdout.splitlines()[0]
    assert slave.startswith('/dev/pts/')
    # The plants are left alone, and the simulator cleaned up only what it made.
    assert os.readlink(tmp_path / 'tty.path.tmp') == str(victim)
    assert not link_file.exists() and not os.path.lexists(link)


def test_foreign_symlink_at_symlink_path_is_refused(tmp_path, victim):
    link = tmp_path / 'tty'
    link.symlink_to(victim)
    os.lchown(link, 4242, 4242)      # as if another user planted it
    if os.lstat(link).st_uid != 4242:
        pytest.skip('cannot change link ownership here (not root)')
    pty = PtyLink(symlink=str(link))
    with pytest.raises(LinkPathError):
        pty.open()
    assert pty.master is None                       # nothing opened
    assert os.readlink(link) == str(victim) and victim.read_text() == VICTIM_TEXT


@pytest.mark.parametrize('kind', ['directory', 'foreign_file'])
def test_link_file_over_a_directory_or_foreign_file_is_refused(tmp_path, kind):
    link_file = tmp_path / 'tty.path'
    if kind == 'directory':
        link_file.mkdir()
    else:
        link_file.write_text(VICTIM_TEXT)
        os.chown(link_file, 4242, 4242)
        if os.stat(link_file).st_uid != 4242:
            pytest.skip('cannot change file ownership here (not root)')
    with pytest.raises(LinkPathError):
        PtyLink(link_file=str(link_file)).open()
    if kind == 'foreign_file':
        assert link_file.read_text() == VICTIM_TEXT


def test_own_leftovers_are_replaced_and_replug_repoints(tmp_path):
    link, link_file = tmp_path / 'tty', tmp_path / 'tty.path'
    link.symlink_to('/dev/pts/999999')              # our own stale link from a crash
    link_file.write_text('/dev/pts/999999\n')
    pty = PtyLink(symlink=str(link), link_file=str(link_file))
    first = pty.open()
    assert os.readlink(link) == first and link_file.read_text() == first + '\n'
    pty.close()
    second = pty.open()                             # replug: a new pair, same paths
    assert os.readlink(link) == second and link_file.read_text() == second + '\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['tty', 'tty.path']   # no temps
    pty.close()
    pty.remove_links()
    assert not os.path.lexists(link) and not link_file.exists()


def test_remove_links_spares_what_replaced_ours(tmp_path, victim):
    link_file = tmp_path / 'tty.path'
    pty = PtyLink(link_file=str(link_file))
    pty.open()
    link_file.unlink()
    link_file.symlink_to(victim)                     # swapped after we wrote it
    pty.close()
    pty.remove_links()
    assert os.readlink(link_file) == str(victim) and victim.read_text() == VICTIM_TEXT
