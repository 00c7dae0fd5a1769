"""Model registry: a stress model from a model name and a medium."""
from __future__ import annotations

from .agarwal import AgarwalRFT
from .base import StressModel
from .media import Medium
from .treers import LiTreersRFT

MODELS = ('agarwal', 'li')
DEFAULT_MODEL = 'agarwal'


def make_model(name: str, medium: Medium) -> StressModel:
    """'agarwal' (default): Agarwal 3D-RFT with (xi_n, mu_surf); 'li': Li 2013 in Treers' 3D."""
    key = name.strip().lower()
    if key == 'agarwal':
        return AgarwalRFT(medium.xi_n, medium.mu_surf)
    if key == 'li':
        return LiTreersRFT(zeta=medium.zeta, coefficients=medium.li_coefficients)
    raise ValueError(f'unknown RFT model {name!r}; known models: {", ".join(MODELS)}')
