"""Granular media: named presets and user parameters for the RFT models.

Agarwal 3D-RFT takes two parameters: the depth-scaled stress scale xi_n (N/m^3) and the
intruder-surface friction mu_surf. Li 2013 takes one scale zeta (N/m^3 here; the literature
quotes N/cm^3 = 1e6 N/m^3). Values and their sources: docs/design/models-rft.md.
"""
from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from rftgls_conventions import G  # m/s^2


class MediumError(ValueError):
    """A medium that cannot be used: unknown preset, unreadable file, missing or ill-typed
    parameter."""


def xi_n_from_friction(rho_c: float, mu_int: float) -> float:
    """Agarwal's media scale xi_n = rho_c g (894 mu^3 - 386 mu^2 + 89 mu), N/m^3."""
    return rho_c * G * (894.0 * mu_int ** 3 - 386.0 * mu_int ** 2 + 89.0 * mu_int)


@dataclass(frozen=True)
class Medium:
    """A granular medium as the RFT models see it.

    xi_n: Agarwal stress scale, N/m^3 (horizontal plate pushed down: 0.875 xi_n per m depth).
    mu_surf: intruder-surface friction (inf = fully rough).
    zeta: Li 2013 scale, N/m^3; stress = zeta x the coefficient set. For the 'generic' set
        (normalised to 1 for a horizontal plate pushed down) zeta is that plate's stress per
        m of depth; the poppy-seed sets are already in N/cm^3, so their presets use
        zeta = 1 N/cm^3 = 1e6 N/m^3 and the plate value is 0.254e6 (LP) or 0.464e6 (CP).
    li_coefficients: which Li coefficient set ('generic', 'poppy_lp', 'poppy_cp').
    """

    name: str
    xi_n: float
    mu_surf: float
    zeta: float
    li_coefficients: str = 'generic'
    note: str = ''

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise MediumError(f'medium name must be a non-empty string, got {self.name!r}')
        for key in ('li_coefficients', 'note'):
            if not isinstance(getattr(self, key), str):
                raise MediumError(f'medium {self.name!r}: {key} must be a string, got '
                                  f'{getattr(self, key)!r}')
        for key in ('xi_n', 'mu_surf', 'zeta'):
            value = getattr(self, key)
            # bool is an int in Python; JSON true/false or null or "3e5" is not a parameter.
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise MediumError(f'medium {self.name!r}: {key} must be a number, got '
                                  f'{value!r}')
        for key, value in (('xi_n', self.xi_n), ('zeta', self.zeta)):
            if not (math.isfinite(value) and value > 0.0):
                raise MediumError(f'medium {self.name!r}: {key} must be a positive number, '
                                  f'got {value}')
        if not (self.mu_surf >= 0.0):  # also rejects NaN; inf is allowed
            raise MediumError(f'medium {self.name!r}: mu_surf must be >= 0, got {self.mu_surf}')

    def to_dict(self) -> dict:
        return asdict(self)


# zeta = 0.875 xi_n makes the two models agree on a horizontal plate pushed down (4.5).
PRESETS: dict[str, Medium] = {
    'glass_beads': Medium(
        'glass_beads', xi_n=3.8e5, mu_surf=0.4, zeta=0.33e6,
        note='0.8 mm glass beads (paper sec. IV); zeta = 0.33 N/cm^3 from Treers 2021; '
             'xi_n = zeta / 0.875; mu_surf from public 3D-RFT code (docs/design/models-rft.md)'),
    'm90_sand': Medium(
        'm90_sand', xi_n=6.8e5, mu_surf=0.4, zeta=0.6e6,
        note='M90 silver sand simulant (paper sec. VI); rho_c = 1600, mu_int = 0.45 '
             '(docs/design/models-rft.md), equivalent to Li zeta ~ 0.6 N/cm^3'),
    'poppy_lp': Medium(
        'poppy_lp', xi_n=2.9e5, mu_surf=0.4, zeta=1.0e6, li_coefficients='poppy_lp',
        note='loosely packed poppy seeds; Li LP coefficient set is already in N/cm^3 '
             '(zeta = 1 N/cm^3 multiplies it unchanged); xi_n = 0.254 N/cm^3 / 0.875'),
    'poppy_cp': Medium(
        'poppy_cp', xi_n=5.3e5, mu_surf=0.4, zeta=1.0e6, li_coefficients='poppy_cp',
        note='closely packed poppy seeds; Li CP set in N/cm^3; xi_n = 0.464 N/cm^3 / 0.875'),
}


def get_medium(name: str) -> Medium:
    key = name.strip().lower().replace('-', '_').replace(' ', '_')
    if key not in PRESETS:
        raise MediumError(f'unknown medium {name!r}; known media: {", ".join(sorted(PRESETS))}')
    return PRESETS[key]


def custom_medium(xi_n: float | None = None, mu_surf: float | None = None,
                  zeta: float | None = None) -> Medium:
    """A user medium. Missing values follow from the given ones (zeta = 0.875 xi_n)."""
    if xi_n is None and zeta is None:
        raise MediumError('give xi_n (Agarwal) or zeta (Li)')
    if xi_n is None:
        assert zeta is not None
        xi_n = zeta / 0.875
    if zeta is None:
        zeta = 0.875 * xi_n
    return Medium('custom', xi_n=float(xi_n), mu_surf=float(0.4 if mu_surf is None else mu_surf),
                  zeta=float(zeta))


def medium_from_dict(d: object) -> Medium:
    """A Medium from a dict with its field names (extra keys, e.g. confidence intervals of a
    calibration, are ignored), its parameters inside their physical ranges (quantities.py:
    a file, a bag or a parameter is input, not a search value)."""
    from ..quantities import MU_SURF, XI_N, ZETA
    if not isinstance(d, dict):
        raise MediumError(f'a medium description is a JSON object, got {type(d).__name__}')
    names = {f.name for f in fields(Medium)}
    missing = {'name', 'xi_n', 'mu_surf', 'zeta'} - set(d)
    if missing:
        raise MediumError(f'medium description lacks {", ".join(sorted(missing))}')
    medium = Medium(**{k: d[k] for k in names if k in d})
    for q, value in ((XI_N, medium.xi_n), (MU_SURF, medium.mu_surf), (ZETA, medium.zeta)):
        problem = q.violation(value)
        if problem:
            raise MediumError(f'medium {medium.name!r}: {problem}')
    return medium


def load_medium(spec: str) -> Medium:
    """A preset name, or a medium JSON file (as `rftgls calibrate` writes)."""
    from rftgls_conventions.safe_read import load_json
    path = Path(spec)
    preset = spec.strip().lower().replace('-', '_').replace(' ', '_') in PRESETS
    if path.suffix == '.json' or (os.path.lexists(path) and not preset):
        try:
            data = load_json(path, 'medium', 'medium file')
        except ValueError as exc:
            raise MediumError(str(exc)) from None
        try:
            return medium_from_dict(data)
        except MediumError as exc:
            raise MediumError(f'{spec}: {exc}') from None
    return get_medium(spec)


# Without a calibration the medium's 1-sigma spread is assumed (`rftgls figure fig10b`'s
# defaults): 10 % of xi_n and 0.1 of mu_surf. Neither is a measurement.
ASSUMED_XI_REL_SIGMA = 0.10
ASSUMED_MU_SIGMA = 0.1


def medium_covariance(spec: str | None, xi_n: float, xi_rel_sigma: float = ASSUMED_XI_REL_SIGMA,
                      mu_sigma: float = ASSUMED_MU_SIGMA) -> tuple[np.ndarray, str]:
    """The (xi_n, mu_surf) covariance of a medium and where it comes from: the calibration
    covariance of a medium JSON written by `rftgls calibrate` ('calibrated'), else the assumed
    sigmas about xi_n ('assumed'). MediumError on a malformed calibration covariance."""
    from rftgls_conventions.safe_read import load_json
    if spec and spec.endswith('.json'):
        try:
            doc = load_json(spec, 'medium', 'medium file')
        except ValueError as exc:
            raise MediumError(str(exc)) from None
        cal = doc.get('calibration', {}) if isinstance(doc, dict) else {}
        cov = cal.get('covariance') if isinstance(cal, dict) else None
        if cov is not None:
            try:
                arr = np.asarray(cov, dtype=float)
            except (TypeError, ValueError):
                arr = np.zeros(0)
            if arr.shape != (2, 2) or not np.all(np.isfinite(arr)):
                raise MediumError(f'{spec}: calibration covariance must be a 2 x 2 matrix of '
                                  'finite numbers')
            return arr, 'calibrated'
    return np.diag([(xi_rel_sigma * xi_n) ** 2, mu_sigma ** 2]), 'assumed'
