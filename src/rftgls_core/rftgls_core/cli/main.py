"""`rftgls`: the RFT-GLS command line. One sub-command per module in this folder.

Error contract (README "Command-line contract"): every error ends with ONE line on stderr and
exit status 2, never a traceback. One handler, here, maps the project's own errors to that
line: they are all ValueError subclasses (MeshError, MapFileError, MediumError, the lab's
BagError, the nodes' ConfigError) or OSError (missing/unreadable files). argparse errors are
one line too (RftglsParser.error). Anything else is a bug: one line, exit 3
('internal error'), and the traceback only with RFTGLS_DEBUG=1.
"""
from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
import warnings
from importlib.metadata import entry_points

from rftgls_conventions import one_line

# sub-command -> module in rftgls_core.cli; each has add_parser(subparsers) and run(args).
COMMANDS = ('wrench', 'capacity', 'plot', 'bench', 'demo', 'chart', 'map', 'simulate', 'plan',
            'figure')
EXIT_USAGE = 2      # bad input of any kind (the CLI contract)
EXIT_INTERNAL = 3   # a bug: an exception the project does not define

# argparse only takes '-5' and '-.5' as values, so '--h -1e-3' would read as an option.
_NEGATIVE_NUMBER = re.compile(r'^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$')


_SEEN = '_rftgls_options_seen'


class _StoreOnce(argparse._StoreAction):
    """argparse's 'store', refusing a second occurrence: `--h 1 --h 2` silently kept 2.
    Options that may repeat say so (action='append') and are combined by their command."""

    def __call__(self, parser, namespace, values, option_string=None):
        seen = getattr(namespace, _SEEN, None)
        if seen is None:
            seen = set()
            setattr(namespace, _SEEN, seen)
        if option_string is not None and self.dest in seen:
            raise argparse.ArgumentError(self, 'given more than once; give it once (a '
                                         'repeated value would be silently dropped)')
        seen.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


class RftglsParser(argparse.ArgumentParser):
    """ArgumentParser with the CLI contract: one-line errors (exit 2), negative numbers in
    scientific notation accepted as values, a single-valued option given twice refused.
    Sub-parsers inherit the class."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER
        self.register('action', None, _StoreOnce)
        self.register('action', 'store', _StoreOnce)

    def parse_known_args(self, args=None, namespace=None):
        ns, extras = super().parse_known_args(args, namespace)
        if hasattr(ns, _SEEN):
            delattr(ns, _SEEN)
        return ns, extras

    def error(self, message: str):
        self.exit(EXIT_USAGE, f'{self.prog}: error: {one_line(message)} (see {self.prog} '
                              f'--help)\n')


def build_parser() -> argparse.ArgumentParser:
    parser = RftglsParser(
        prog='rftgls', description='RFT granular limit surfaces: wrenches, load capacity, '
        'slip twists, state-space maps. SI inside; CLI angles in degrees.')
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    for name in COMMANDS:
        try:
            module = importlib.import_module(f'rftgls_core.cli.{name}')
        except ModuleNotFoundError as exc:
            if exc.name == f'rftgls_core.cli.{name}':
                continue  # not written yet
            raise
        module.add_parser(sub)
    # Other packages add sub-commands through entry points (e.g. rftgls_ros adds
    # `calibrate`), so the core never imports them.
    for ep in entry_points(group='rftgls.commands'):
        try:
            ep.load()(sub)
        except Exception as exc:  # a broken plugin must not take the core CLI down
            print(f'rftgls: warning: command {ep.name!r} unavailable: {one_line(exc)}',
                  file=sys.stderr)
    return parser


def cli_contract(prog: str):
    """Decorator giving a program's `main(argv) -> int` the CLI contract of this module: a
    ValueError or OSError (bad input: the project's own errors, unreadable files) is one
    line `PROG: error: ...` and exit 2; anything else one line `internal error` and exit 3
    (the traceback with RFTGLS_DEBUG=1); Ctrl-C exit 130. For `rftgls` itself, the lab
    tools and behavior_demo, whose parsers are RftglsParser (one-line usage errors)."""
    import functools

    def wrap(main):
        @functools.wraps(main)
        def run(*args, **kwargs) -> int:
            debug = bool(os.environ.get('RFTGLS_DEBUG'))
            try:
                return main(*args, **kwargs)
            except KeyboardInterrupt:
                print(f'{prog}: interrupted', file=sys.stderr)
                return 130
            except (ValueError, OSError) as exc:
                if debug:
                    raise
                print(f'{prog}: error: {one_line(exc)}', file=sys.stderr)
                return EXIT_USAGE
            except Exception as exc:  # noqa: BLE001 -- a bug, still no traceback by default
                if debug:
                    raise
                print(f'{prog}: internal error ({type(exc).__name__}): {one_line(exc)}; '
                      'RFTGLS_DEBUG=1 shows the traceback', file=sys.stderr)
                return EXIT_INTERNAL
        return run
    return wrap


def _print_warnings(prefix: str, caught) -> None:
    for w in caught:
        print(f'{prefix}: warning: {one_line(w.message)}', file=sys.stderr)


def without_ros_args(argv: list[str]) -> list[str]:
    """argv without the ROS arguments `ros2 run rftgls_core rftgls ... --ros-args ...` appends:
    from `--ros-args` up to a closing `--` or the end, the grammar rcl documents. The core
    stays ROS-free, so this is the one place that does not ask rclpy's parser: it has no ROS
    argument to apply, only to ignore."""
    out, in_ros = [], False
    for a in argv:
        if a == '--ros-args':
            in_ros = True
        elif in_ros and a == '--':
            in_ros = False
        elif not in_ros:
            out.append(a)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(without_ros_args(sys.argv[1:] if argv is None else argv))
    except SystemExit as exc:       # --help (0) and argparse errors (2, one line)
        return int(exc.code or 0) if not isinstance(exc.code, str) else EXIT_USAGE
    return cli_contract(f'rftgls {args.command}')(_run)(args)


def _run(args: argparse.Namespace) -> int:
    """The sub-command. Its warnings (repaired mesh, unverified map, ...) are printed one line
    each after a run that succeeds; when the run fails, the error line is the only line."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('default')
        code = int(args.run(args) or 0)
    _print_warnings(f'rftgls {args.command}', caught)
    return code


if __name__ == '__main__':
    sys.exit(main())
