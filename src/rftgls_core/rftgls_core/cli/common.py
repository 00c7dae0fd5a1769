"""Argument groups and conversions shared by sub-commands (degrees and mm only here)."""
from __future__ import annotations

import argparse
import json
import math

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


def bounded_int(lo: int, hi: int, what: str = 'value'):
    """An argparse type: an integer in [lo, hi] (a clear one-line message otherwise)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'not an integer: {text!r}') from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f'{what} must be in {lo}..{hi}, got {value}')
        return value
    return parse


# Twists sampled per state: below 8 no surface can be fitted; 100 000 already takes minutes
# per state (the brute-force reference of the tests), more only exhausts memory.
MIN_TWISTS, MAX_TWISTS = 8, 100_000
twist_count = bounded_int(MIN_TWISTS, MAX_TWISTS, 'twist count')


def nonneg_float_or_inf(text: str) -> float:
    """A number >= 0; inf allowed (a fully rough surface), NaN not."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f'must be >= 0, got {text!r}')
    return value


def add_medium_args(p: argparse.ArgumentParser, default: str | None = None) -> None:
    g = p.add_argument_group('granular medium (a preset, or the model parameters)')
    g.add_argument('--model', default=DEFAULT_MODEL, choices=MODELS,
                   help='RFT model (default: %(default)s)')
    g.add_argument('--medium', default=None,
                   help='preset (glass_beads, m90_sand, poppy_lp, poppy_cp) or a medium JSON '
                        'file written by `rftgls calibrate`'
                        + (f' (default: {default})' if default else ''))
    g.add_argument('--xi-n', type=finite_float, help='Agarwal stress scale xi_n, N/m^3')
    g.add_argument('--mu-surf', type=nonneg_float_or_inf,
                   help='Agarwal intruder-surface friction (inf allowed)')
    g.add_argument('--zeta', type=finite_float, help='Li scale zeta, N/m^3 (1 N/cm^3 = 1e6)')
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
