"""The end of every map-slice plot (`rftgls map plot`, robot and described maps alike):
legend, save, and a one-line summary of what the slice shows."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def save_slice(fig, axp, out: str | Path, cap: np.ndarray, unsup: np.ndarray) -> int:
    """Legend, save, and the one-line summary of a map slice (pixels with a value,
    unsupported, capacity range in N); the exit code 0."""
    from .figure_io import save
    axp.legend(loc='upper right', fontsize=7)
    out = Path(out)
    save(fig, out)
    valued = int(np.isfinite(cap).sum())
    print(f'{out}: {valued} of {cap.size} pixels with a value, {int(unsup.sum())} unsupported, '
          f'capacity {np.nanmin(cap) if valued else math.nan:.3g} .. '
          f'{np.nanmax(cap) if valued else math.nan:.3g} N')
    return 0
