"""Li, Zhang & Goldman 2013 (Science 339:1408) generic 2D RFT: the 9-term Fourier fit.

In the vertical plane that holds the plate normal and the velocity, with a horizontal unit
vector x_hat and z_hat up (docs/design/models-rft.md):
- beta, attack angle: tilt of the plate line; the downward plate normal is
  n_d = sin(beta) x_hat - cos(beta) z_hat (beta = 0 horizontal plate, +-pi/2 vertical).
- gamma, intrusion angle: v_hat = cos(gamma) x_hat - sin(gamma) z_hat (pi/2 straight down).
- stress per unit depth on the plate: alpha = -alpha_x x_hat + alpha_z z_hat.

The fit (section 2.2), with the pairing C <-> cosine, D <-> sine:
    alpha_z = A00 + A10 cos 2b + B11 sin(2b + g) + B01 sin g + B-11 sin(g - 2b)
    alpha_x = C11 cos(2b + g) + C01 cos g + C-11 cos(g - 2b) + D10 sin 2b
It is pi-periodic in beta and valid for any gamma in (-pi, pi] (mirror relations, 2.5), so the
3D decomposition (rft/treers.py) can evaluate it without branch-wise mirroring. The fit is
written on (cos 2b, sin 2b, cos g, sin g) so that callers holding vectors need no trigonometry.

The 3D model users instantiate, LiTreersRFT (Li inside Treers' decomposition), lives in
rft/treers.py and is re-exported here.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

N_PER_CM3 = 1e6   # N/m^3 per N/cm^3 (1 cm^-3 = 1e6 m^-3)


@dataclass(frozen=True)
class LiCoefficients:
    """The nine non-zero Fourier coefficients of one Li 2013 fit (docs/design/models-rft.md).

    unit: 'dimensionless' for the generic set (multiplied by the medium's zeta), or 'N/cm^3'
    for medium-specific sets (the fit is the stress per depth itself, in Li's units).
    """

    name: str
    unit: str
    A00: float
    A10: float
    B11: float
    B01: float
    Bm11: float     # B_{-1,1}
    C11: float
    C01: float
    Cm11: float     # C_{-1,1}
    D10: float
    source: str = ''

    def alpha_cs(self, cos2b, sin2b, cosg, sing) -> tuple[np.ndarray, np.ndarray]:
        """(alpha_x, alpha_z) in this set's unit from cos/sin of 2 beta and of gamma."""
        cos2b, sin2b = np.asarray(cos2b, dtype=float), np.asarray(sin2b, dtype=float)
        cosg, sing = np.asarray(cosg, dtype=float), np.asarray(sing, dtype=float)
        cos_p = cos2b * cosg - sin2b * sing          # cos(2b + g)
        sin_p = sin2b * cosg + cos2b * sing          # sin(2b + g)
        cos_m = cosg * cos2b + sing * sin2b          # cos(g - 2b)
        sin_m = sing * cos2b - cosg * sin2b          # sin(g - 2b)
        alpha_z = (self.A00 + self.A10 * cos2b + self.B11 * sin_p + self.B01 * sing
                   + self.Bm11 * sin_m)
        alpha_x = self.C11 * cos_p + self.C01 * cosg + self.Cm11 * cos_m + self.D10 * sin2b
        return alpha_x, alpha_z

    def alpha(self, beta, gamma) -> tuple[np.ndarray, np.ndarray]:
        """(alpha_x, alpha_z) in this set's unit for angles beta, gamma in rad."""
        two_b = 2.0 * np.asarray(beta, dtype=float)
        gamma = np.asarray(gamma, dtype=float)
        return self.alpha_cs(np.cos(two_b), np.sin(two_b), np.cos(gamma), np.sin(gamma))

    @property
    def penetration(self) -> float:
        """alpha_z(beta = 0, gamma = pi/2): a horizontal plate pushed straight down."""
        return self.A00 + self.A10 + self.B11 + self.B01 + self.Bm11

    @property
    def drag(self) -> float:
        """alpha_x(0, 0): a horizontal plate dragged sideways (Treers' simplest alpha_1)."""
        return self.C11 + self.C01 + self.Cm11

    def as_dict(self) -> dict:
        return asdict(self)


# (docs/design/models-rft.md.) Generic: Li 2013 Table S2 as quoted by four public codes;
# normalised so that penetration == 1.000.
GENERIC = LiCoefficients('generic', 'dimensionless', 0.206, 0.169, 0.212, 0.358, 0.055,
                         -0.124, 0.253, 0.007, 0.088,
                         source='Li et al. 2013 Table S2 (docs/design/models-rft.md)')
# Poppy seeds, already in N/cm^3 (jnskkmhr/IsaacLab material.py, docs/design/models-rft.md).
POPPY_LP = LiCoefficients('poppy_lp', 'N/cm^3', 0.051, 0.047, 0.053, 0.083, 0.020,
                          -0.026, 0.057, 0.000, 0.025,
                          source='poppy seeds, loosely packed (docs/design/models-rft.md)')
POPPY_CP = LiCoefficients('poppy_cp', 'N/cm^3', 0.094, 0.092, 0.092, 0.151, 0.035,
                          -0.039, 0.086, 0.018, 0.046,
                          source='poppy seeds, closely packed (docs/design/models-rft.md)')

COEFFICIENT_SETS: dict[str, LiCoefficients] = {c.name: c for c in (GENERIC, POPPY_LP, POPPY_CP)}


def coefficient_set(name: str | LiCoefficients) -> LiCoefficients:
    if isinstance(name, LiCoefficients):
        return name
    try:
        return COEFFICIENT_SETS[name]
    except KeyError:
        raise ValueError(f'unknown Li coefficient set {name!r}; '
                         f'choose from {sorted(COEFFICIENT_SETS)}') from None


def li_alpha(beta, gamma, coefficients: str | LiCoefficients = 'generic'
             ) -> tuple[np.ndarray, np.ndarray]:
    """(alpha_x, alpha_z) of Li's fit in the set's own unit (generic: per unit zeta)."""
    return coefficient_set(coefficients).alpha(beta, gamma)


def __getattr__(name: str):
    # LiTreersRFT lives in rft/treers.py (which imports this module); lazy to avoid a cycle.
    if name == 'LiTreersRFT':
        from .treers import LiTreersRFT
        return LiTreersRFT
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
