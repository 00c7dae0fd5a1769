"""Argument groups and conversions shared by sub-commands (degrees and mm only here)."""
from __future__ import annotations

import argparse
import json
import math

from ..quantities import MU_SURF, XI_N, ZETA, bounded_int
from ..rft.media import Medium, custom_medium, load_medium
from ..rft.models import DEFAULT_MODEL, MODELS


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be finite, got {text!r}')
    return value


# Twists sampled per state: below 8 no surface can be fitted; 100 000 already takes minutes
# per state (the brute-force reference of the tests), more only exhausts memory.
MIN_TWISTS, MAX_TWISTS = 8, 100_000
twist_count = bounded_int(MIN_TWISTS, MAX_TWISTS, 'twist count')


def add_medium_args(p: argparse.ArgumentParser, default: str | None = None) -> None:
    g = p.add_argument_group('granular medium (a preset, or the model parameters)')
    g.add_argument('--model', default=DEFAULT_MODEL, choices=MODELS,
                   help='RFT model (default: %(default)s)')
    g.add_argument('--medium', default=None,
                   help='preset (glass_beads, m90_sand, poppy_lp, poppy_cp) or a medium JSON '
                        'file written by `rftgls calibrate`'
                        + (f' (default: {default})' if default else ''))
    g.add_argument('--xi-n', type=XI_N.arg, help='Agarwal stress scale xi_n, N/m^3 '
                   f'({XI_N.lo:g}..{XI_N.hi:g})')
    g.add_argument('--mu-surf', type=MU_SURF.arg,
                   help=f'Agarwal intruder-surface friction ({MU_SURF.lo:g}..{MU_SURF.hi:g}, '
                        'or inf: fully rough)')
    g.add_argument('--zeta', type=ZETA.arg, help='Li scale zeta, N/m^3 (1 N/cm^3 = 1e6; '
                   f'{ZETA.lo:g}..{ZETA.hi:g})')
    p.set_defaults(default_medium=default)


def medium_from_args(args) -> Medium:
    custom = any(v is not None for v in (args.xi_n, args.mu_surf, args.zeta))
    if custom and args.medium:
        raise ValueError('give either --medium or medium parameters, not both')
    if custom:
        return custom_medium(xi_n=args.xi_n, mu_surf=args.mu_surf, zeta=args.zeta)
    name = args.medium or args.default_medium
    if name is None:
        raise ValueError('give --medium NAME or --xi-n/--mu-surf or --zeta')
    return load_medium(name)


def print_json(obj) -> None:
    print(json.dumps(obj, indent=2, allow_nan=False))
