"""Headless pyplot and one way to write a figure, for every chart in this folder."""
from __future__ import annotations

from pathlib import Path

from rftgls_conventions.safe_write import atomic_write, output_file

# The formats a figure file may have (its suffix says which; nothing is appended).
FIGURE_SUFFIXES = ('.png', '.pdf', '.svg')


def pyplot():
    """matplotlib.pyplot on the Agg backend (charts are files; no display on robots or CI)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def figure_path(out: str | Path, label: str = '--out') -> Path:
    """The figure file an option names, checked before any work (safe_write.output_file): a
    file ending in .png, .pdf or .svg, not a folder, in a writable folder."""
    return output_file(out, label, FIGURE_SUFFIXES)


def save(fig, out: str | Path, dpi: int = 110) -> None:
    """Lay out, write `out` atomically (safe_write: a planted link is replaced, never
    followed; the format is the suffix's) and free the figure."""
    try:
        out = figure_path(out, 'figure')
        fig.tight_layout()
        with atomic_write(out) as tmp:
            fig.savefig(tmp, dpi=dpi, format=out.suffix.lower().lstrip('.'))
    finally:
        pyplot().close(fig)
