"""The tug as a time series (ROS-free): what behavior_node saw of capacity_node while it ran.

One sample per capacity estimate: time (s since the first sample, behavior_node's clock),
tension, capacity and its lower bound (N, NaN without a value), capacity_node's status, the
behaviour state at that moment, and the anchor state the estimate was computed at (tether
angle phi, height of p, body pitch, proximal and distal leg angles; rad and m, NaN when the
estimate had none), so a lower bound that differs from the one a decision expected can be
traced to the pose it was taken at. ``plot_tug_series`` draws them with the margin guard lines the
machine acts on (``slow_ratio`` and ``stop_ratio`` times the lower bound: a decision uses the
lower bound, not the point estimate), shades the time spent
in TUG and marks every estimate without a usable status; ``write_tug_series`` also writes the
samples as CSV. The demo writes both next to the cycle report (``<stem>_tug.png/.csv``).
"""
from __future__ import annotations

import csv
import io
import math
from collections import deque
from dataclasses import astuple, dataclass, fields
from pathlib import Path

from rftgls_conventions.safe_write import write_text
from rftgls_core.charts.figure_io import save

USABLE = ('ok', 'assumed')


@dataclass(frozen=True)
class TugSample:
    t_s: float
    tension_n: float
    capacity_n: float
    capacity_lower_n: float
    status: str
    state: str
    phi_rad: float = math.nan
    h_m: float = math.nan
    theta_b_rad: float = math.nan
    theta_l1_rad: float = math.nan
    theta_l2_rad: float = math.nan


NO_POSE = (math.nan,) * 5


class TugSeries:
    """Bounded record of TugSample (the oldest go first past ``maxlen``)."""

    def __init__(self, maxlen: int = 100_000):
        self.samples: deque[TugSample] = deque(maxlen=maxlen)
        self._t0: float | None = None

    def add(self, t: float, tension: float, capacity: float, lower: float, status: str,
            state: str, pose: tuple[float, ...] = NO_POSE) -> None:
        """pose: (phi rad, h m, theta_B rad, theta_L1 rad, theta_L2 rad) of the estimate."""
        if self._t0 is None:
            self._t0 = t
        self.samples.append(TugSample(t - self._t0, float(tension), float(capacity),
                                      float(lower), status, state,
                                      *(float(x) for x in pose)))


def _spans(ts: list[float], flags: list[bool]) -> list[tuple[float, float]]:
    """[t_start, t_end] of each run of True flags."""
    out, start = [], None
    for t, f in zip(ts, flags):
        if f and start is None:
            start = t
        elif not f and start is not None:
            out.append((start, t))
            start = None
    if start is not None:
        out.append((start, ts[-1]))
    return out


def plot_tug_series(samples, path: str | Path, slow_ratio: float | None = 0.90,
                    stop_ratio: float = 0.97, title: str = '') -> Path:
    """Write the PNG; returns its path (slow_ratio None: no slow-down line). Raises
    ValueError on an empty series."""
    samples = list(samples)
    if not samples:
        raise ValueError('no samples to plot')
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    t = [s.t_s for s in samples]
    cap = [s.capacity_n if s.status in USABLE else math.nan for s in samples]
    fig, (ax, ax_s) = plt.subplots(2, 1, figsize=(11, 5.5), sharex=True,
                                   gridspec_kw={'height_ratios': [4, 1]})
    for i, (a, b) in enumerate(_spans(t, [s.state == 'TUG' for s in samples])):
        ax.axvspan(a, b, color='tab:green', alpha=0.08, label='TUG' if i == 0 else None)
    ax.plot(t, [s.tension_n for s in samples], color='tab:blue', lw=1.2, label='tension')
    ax.plot(t, cap, color='k', lw=1.2, label='capacity')
    lower = [s.capacity_lower_n if s.status in USABLE else math.nan for s in samples]
    ax.plot(t, lower, color='0.45', lw=1, ls='--', label='lower bound')
    if slow_ratio is not None:
        ax.plot(t, [slow_ratio * c for c in lower], color='tab:orange', lw=0.8, ls=':',
                label=f'slow down ({slow_ratio:.2f} lower bound)')
    ax.plot(t, [stop_ratio * c for c in lower], color='tab:red', lw=0.8, ls=':',
            label=f'guard: stop ({stop_ratio:.2f} lower bound)')
    bad = [(s.t_s, s.tension_n) for s in samples if s.status not in USABLE]
    if bad:
        ax.plot(*zip(*bad), 'x', color='tab:red', ms=3, label='no usable estimate')
    ax.set_ylabel('force along the tether [N]')
    ax.legend(loc='upper left', fontsize=7, ncol=3)
    ax.grid(alpha=0.3)
    names = sorted({s.status for s in samples}, key=lambda n: (n not in USABLE, n))
    level = {n: i for i, n in enumerate(names)}
    ax_s.scatter(t, [level[s.status] for s in samples], s=4,
                 c=['tab:green' if s.status == 'ok' else 'tab:olive' if s.status in USABLE
                    else 'tab:red' for s in samples])
    ax_s.set_yticks(range(len(names)), names, fontsize=7)
    ax_s.set_ylim(-0.5, len(names) - 0.5)
    ax_s.set_xlabel('time [s]')
    ax_s.set_ylabel('status', fontsize=8)
    fig.suptitle(title or 'tug: tension, capacity and guard lines (capacity_node estimates)')
    path = Path(path)
    save(fig, path)     # layout, folder, write, free
    return path


def write_tug_series(series: TugSeries, out_dir: str | Path, stem: str,
                     slow_ratio: float | None = 0.90, stop_ratio: float = 0.97,
                     title: str = '') -> tuple[Path, Path] | None:
    """``stem``_tug.csv and ``stem``_tug.png in ``out_dir``; None when nothing was recorded."""
    csv_path = write_tug_csv(series, out_dir, stem)
    if csv_path is None:
        return None
    png = plot_tug_series(series.samples, csv_path.with_suffix('.png'), slow_ratio, stop_ratio,
                          title)
    return csv_path, png


def write_tug_csv(series: TugSeries, out_dir: str | Path, stem: str) -> Path | None:
    """The table alone, ``stem``_tug.csv in ``out_dir``; None when nothing was recorded."""
    if not series.samples:
        return None
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f'{stem}_tug.csv'
    with io.StringIO(newline='') as f:
        w = csv.writer(f)
        w.writerow([fl.name for fl in fields(TugSample)])
        w.writerows(astuple(s) for s in series.samples)
        write_text(csv_path, f.getvalue())     # atomic; a planted link is replaced
    return csv_path
