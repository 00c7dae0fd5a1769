"""The one-at-a-time sensitivity of the multibody predictions (multibody/sensitivity.py): each
prediction's nominal value, the paper's value, and the value with one input changed."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figure_io import save

PANELS = (('DH', 'h_m', 'DH h, mm', 1e3), ('DL', 'h_m', 'DL h, mm', 1e3),
          ('SH', 'h_m', 'SH h, mm', 1e3), ('DH', 'theta_b_deg', 'DH theta_B, deg', 1.0),
          ('DL', 'theta_b_deg', 'DL theta_B, deg', 1.0),
          ('SH', 'theta_b_deg', 'SH theta_B, deg', 1.0),
          ('DH/SH', None, 'energy DH / SH', 1.0), ('DL/SH', None, 'energy DL / SH', 1.0),
          ('walk', 'distance_m', 'walk in 8 s, mm', 1e3))


def _value(result: dict, key: str, field: str | None, scale: float) -> float:
    v = result.get(key)
    if field is not None:
        v = None if v is None else v.get(field)
    return np.nan if v is None else float(v) * scale


def _paper(data: dict, key: str, field: str | None, scale: float) -> float:
    p = data['paper']
    if key in p['table_ii']:
        return p['table_ii'][key][field] * scale
    if key in p['energy_ratios']:
        return p['energy_ratios'][key]
    return p['walk_m_per_8s'] * scale


def plot_sensitivity(data: dict, path: str | Path) -> Path:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    sweeps = data['sweeps']
    labels = [f"{s['label']} {s['value']}" for s in sweeps]
    fig, axes = plt.subplots(3, 3, figsize=(13, 11), sharey=True)
    y = np.arange(len(sweeps))
    for ax, (key, field, title, scale) in zip(axes.ravel(), PANELS):
        nominal = _value(data['nominal'], key, field, scale)
        vals = np.array([_value(s['result'], key, field, scale) for s in sweeps])
        ax.barh(y, vals - nominal, left=nominal, color='tab:blue', alpha=0.7)
        ax.axvline(nominal, color='k', lw=1, label='model, nominal inputs')
        ax.axvline(_paper(data, key, field, scale), color='tab:red', lw=2, ls='--',
                   label='paper')
        ax.set_title(title, fontsize=10)
        ax.set_yticks(y)
        ax.set_yticklabels(labels, fontsize=7)
        ax.tick_params(axis='x', labelsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle('MiniRQuad on M90 sand: each prediction with one input changed '
                 '(nothing fitted)', fontsize=11)
    path = Path(path)
    save(fig, path, dpi=100)    # atomic, through safe_write; closes the figure
    return path
