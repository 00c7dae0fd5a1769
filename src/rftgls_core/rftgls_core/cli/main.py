"""`rftgls`: the RFT-GLS command line. One sub-command per module in this folder.

Bad input (unreadable mesh, NaN or zero twist, unknown medium, ...) ends with one line on
stderr and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from importlib.metadata import entry_points

# sub-command -> module in rftgls_core.cli; each has add_parser(subparsers) and run(args).
COMMANDS = ('wrench', 'capacity', 'plot', 'bench', 'demo', 'chart', 'map', 'simulate', 'figure')


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
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
            print(f'rftgls: warning: command {ep.name!r} unavailable: {exc}', file=sys.stderr)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        print('rftgls: interrupted', file=sys.stderr)
        return 130
    except (ValueError, OSError) as exc:
        print(f'rftgls {args.command}: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
