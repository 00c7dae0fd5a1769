"""Headless pyplot and one way to write a figure, for every chart in this folder."""
from __future__ import annotations

from pathlib import Path


def pyplot():
    """matplotlib.pyplot on the Agg backend (charts are files; no display on robots or CI)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def save(fig, out: str | Path, dpi: int = 110) -> None:
    """Lay out, write `out` (creating its folder) and free the figure."""
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    pyplot().close(fig)
