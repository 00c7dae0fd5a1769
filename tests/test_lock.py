"""requirements/lock.txt is complete: installed with --no-deps, it satisfies every requirement
(with its extras and environment markers) of every distribution it pins and of the stack's own
packages. The metadata comes from the installed distributions (the venv `make setup` built
from this very lock), so a requirement nobody wrote into the lock is caught here and not on a
stranger's machine the day a new release appears."""
from __future__ import annotations

import functools
import importlib.metadata
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'tools'))
import lock  # noqa: E402  (tools/ is not a package)

LOCK_TEXT = (ROOT / 'requirements' / 'lock.txt').read_text()
PINS = lock.read_lock(LOCK_TEXT)
ROOTS = lock.roots_of_project()
# Metadata of the installed distributions, read once for all the lock variants below.
REQUIRES = functools.lru_cache(maxsize=None)(lock.installed_requires)


def _check(text: str) -> list[str]:
    return lock.unmet(lock.read_lock(text), ROOTS, REQUIRES)


def _without_pin(text: str, name: str) -> str:
    """The lock's text with one pin (its line and its hash lines) removed."""
    pattern = re.compile(rf'^{re.escape(name)}(\[[^\]]*\])?==[^\n]*\n(    --hash[^\n]*\n)*',
                         re.MULTILINE | re.IGNORECASE)
    out, n = pattern.subn('', text)
    assert n == 1, name
    return out


def test_the_lock_covers_every_requirement():
    assert _check(LOCK_TEXT) == []


def test_the_installed_set_is_the_locked_set():
    for pin in PINS.values():
        assert importlib.metadata.version(pin.name) == pin.version, pin


@pytest.mark.parametrize('name', sorted(PINS))
def test_removing_any_one_pin_is_caught(name, tmp_path):
    # On a copy of the lock: every pin is needed by something, so each removal is reported.
    copy = tmp_path / 'lock.txt'
    copy.write_text(_without_pin(LOCK_TEXT, name))
    problems = _check(copy.read_text())
    assert problems and all('not in the lock' in p for p in problems)
    assert any(f' requires {name}' in re.sub(r'[._]', '-', p.lower()) for p in problems), problems


def test_a_missing_extra_is_caught():
    # The failure this test exists for: pytest-cov asks for coverage[toml]; a lock listing
    # plain `coverage==...` makes pip (without --no-deps) treat the extra as unpinned.
    text = re.sub(r'^coverage\[toml\]==', 'coverage==', LOCK_TEXT, flags=re.MULTILINE)
    assert text != LOCK_TEXT
    assert any('coverage[toml]' in p and 'extras' in p for p in _check(text))


def test_a_version_a_requirement_excludes_is_caught():
    # colcon-core requires setuptools<80.
    text = re.sub(r'^setuptools==\S+', 'setuptools==80.0.0', LOCK_TEXT, flags=re.MULTILINE)
    assert any('setuptools' in p and 'the lock pins 80.0.0' in p for p in _check(text))


def test_markers_and_extras_decide_what_applies():
    from packaging.requirements import Requirement
    pins = {'a': lock.Pin('a', '1.0'), 'b': lock.Pin('b', '2.0')}
    req = {'a': ['b>=2', 'c; extra == "x"', 'd; python_version < "3"'], 'b': []}
    roots = [(Requirement('a'), 'root')]
    assert lock.unmet(pins, roots, lambda n: req.get(n, [])) == []
    with_x = [(Requirement('a[x]'), 'root')]
    problems = lock.unmet(pins, with_x, lambda n: req.get(n, []))
    assert any('requires c' in p for p in problems)          # the extra pulls c in
    assert any('extras' in p for p in problems)              # and a is not locked with [x]
