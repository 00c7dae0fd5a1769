"""`rftgls`'s contract for what a sub-command raises (rftgls_core/cli/main.py): bad input is one
line `rftgls CMD: error: ...` and exit 2, a bug one line `internal error` and exit 3 (the
traceback only with RFTGLS_DEBUG=1), Ctrl-C exit 130; warnings are printed one line each after
a run that succeeds, and a run that fails prints its error line alone."""
from __future__ import annotations

import argparse
import warnings

import pytest

from rftgls_core.cli import main as cli


def _with_command(monkeypatch, run) -> None:
    """`rftgls probe` runs ``run(args)``."""
    def build_parser() -> argparse.ArgumentParser:
        parser = argparse.ArgumentParser(prog='rftgls')
        sub = parser.add_subparsers(dest='command', required=True)
        sub.add_parser('probe').set_defaults(run=run)
        return parser
    monkeypatch.setattr(cli, 'build_parser', build_parser)
    monkeypatch.delenv('RFTGLS_DEBUG', raising=False)


def _warn_then(result):
    def run(_args):
        warnings.warn('mesh repaired:\n3 faces flipped', UserWarning, stacklevel=1)
        if isinstance(result, BaseException):
            raise result
        return result
    return run


def test_a_run_that_succeeds_prints_each_warning_on_one_line(monkeypatch, capsys):
    _with_command(monkeypatch, _warn_then(0))
    assert cli.main(['probe']) == 0
    assert capsys.readouterr().err == 'rftgls probe: warning: mesh repaired: 3 faces flipped\n'


@pytest.mark.parametrize('exc, code, line', [
    (ValueError('h 0.2 m is outside\nthe map'), cli.EXIT_USAGE,
     'rftgls probe: error: h 0.2 m is outside the map\n'),
    (FileNotFoundError(2, 'No such file or directory', 'x.h5'), cli.EXIT_USAGE,
     "rftgls probe: error: [Errno 2] No such file or directory: 'x.h5'\n"),
    (ZeroDivisionError('float division by zero'), cli.EXIT_INTERNAL,
     'rftgls probe: internal error (ZeroDivisionError): float division by zero; '
     'RFTGLS_DEBUG=1 shows the traceback\n'),
    (KeyboardInterrupt(), 130, 'rftgls probe: interrupted\n'),
])
def test_a_run_that_fails_prints_its_one_line_alone(monkeypatch, capsys, exc, code, line):
    _with_command(monkeypatch, _warn_then(exc))
    assert cli.main(['probe']) == code
    assert capsys.readouterr().err == line


def test_rftgls_debug_shows_the_traceback(monkeypatch):
    _with_command(monkeypatch, _warn_then(ZeroDivisionError('float division by zero')))
    monkeypatch.setenv('RFTGLS_DEBUG', '1')
    with pytest.raises(ZeroDivisionError):
        cli.main(['probe'])
