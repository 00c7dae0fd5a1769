"""Cycle report like the paper's Fig. 12: energy per phase and distance per cycle (CSV + PNG).

Energies in J are the INA219 energy (bridge /energy, idle included) integrated over each phase:
walk (including the unburrow-by-walking), burrow, and the tug's last ``tug_energy_window``
seconds (the paper counts the last 8 s of a tug so that tugs of different lengths compare).
distance_m is the walking time times the assumed walking speed (MiniRQuad has no odometry;
the paper used an ArUco marker), sled_distance_m the tether reeled in while taut: the sled's
travel as the spool sees it (an anchor that gives way shortens the rope too, and nothing on
the robot measures the sled itself).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from rftgls_conventions.safe_read import read_text
from rftgls_conventions.safe_write import write_text
from rftgls_core.charts.figure_io import save

from .tug_series import TugSeries, plot_tug_series, write_tug_csv


@dataclass
class CycleRecord:
    sled_kg: float
    cycle: int
    mode: str
    outcome: str
    walk_j: float
    burrow_j: float
    tug_j: float
    tug_total_j: float
    walk_s: float
    burrow_s: float
    tug_s: float
    distance_m: float
    sled_distance_m: float
    need_n: float
    tension_median_n: float
    min_margin_n: float
    reason: str = ''     # safety reason code of the cycle ('' = none), e.g. estimate_timeout
    slip: str = ''       # the slip recorded in this cycle ('' = none), e.g. slip_pitch: kept
    #                      when a later stop or abort of the cycle sets `reason`
    # The decision basis (NaN: none). lower_n: the lower bound of the mode chosen (refused: of
    # the strongest mode), N, the number the choice was made on; point_n: its point estimate
    # at the Table II pose, N (reported, never decided on); energy_pred_j: its predicted
    # burrow energy, J; reel_lower_margin_n: the smallest (capacity_node lower bound - safety
    # factor x need), N, over the steps the winch reeled in (negative: a tug below the need);
    # decision: the chooser's reason, one line; check_lower_n: the lower bound the last tug
    # was started on (capacity_node's at the measured pose, times the learned scale), N.
    lower_n: float = float('nan')
    point_n: float = float('nan')
    energy_pred_j: float = float('nan')
    reel_lower_margin_n: float = float('nan')
    decision: str = ''
    check_lower_n: float = float('nan')
    # A planned gait's prediction (NaN for a Table II mode): h of p and its sigma, m; pitch,
    # rad; the probability that it holds the required pull (the lower bound's normal model).
    h_pred_m: float = float('nan')
    h_pred_sigma_m: float = float('nan')
    theta_b_pred_rad: float = float('nan')
    p_hold: float = float('nan')

    @property
    def energy_j(self) -> float:
        return self.walk_j + self.burrow_j + self.tug_j

    def summary(self) -> str:
        return (f'cycle {self.cycle} ({1e3 * self.sled_kg:.0f} g sled): {self.mode} '
                f'{self.outcome}' + (f' ({self.reason})' if self.reason else '')
                + (f' after {self.slip}' if self.slip and self.slip != self.reason else '')
                + f'; energy walk {self.walk_j:.2f} J, burrow {self.burrow_j:.2f} J'
                f', tug {self.tug_j:.2f} J (last window; whole tug {self.tug_total_j:.2f} J); '
                f'walked ~{self.distance_m:.3f} m (timed), reeled {self.sled_distance_m:.3f} m '
                'taut (the spool, not the sled)')


def read_csv(path: str | Path) -> list[CycleRecord]:
    out = []
    with io.StringIO(read_text(path, 'report', 'cycle report'), newline='') as f:
        for row in csv.DictReader(f):
            kw = {}
            for fl in fields(CycleRecord):
                v = row.get(fl.name, fl.default)
                kw[fl.name] = int(v) if fl.type in ('int', int) else (
                    v if fl.type in ('str', str) else float(v))
            out.append(CycleRecord(**kw))
    return out


def write_report(records: list[CycleRecord], out_dir: str | Path,
                 stem: str = 'cycle_report') -> tuple[Path, Path]:
    """Write ``stem``.csv and ``stem``.png in ``out_dir``; returns both paths."""
    csv_path = write_report_csv(records, out_dir, stem)
    png_path = csv_path.with_suffix('.png')
    plot_report(records, png_path)
    return csv_path, png_path


def write_run_report(records: list[CycleRecord], series: TugSeries, out_dir: str | Path,
                     stem: str, slow_ratio: float | None, stop_ratio: float
                     ) -> tuple[Path, Path, Path | None]:
    """A run's report: ``stem``.csv, ``stem``_tug.csv, then ``stem``.png and ``stem``_tug.png
    (write_report, write_tug_series): both tables are on disk before either plot is drawn,
    so a stop cut short while plotting (the stop watchdog, launch's SIGKILL; matplotlib is
    slow to start on a robot's computer) loses at most a plot. Returns the cycle table's and
    plot's paths and the tug plot's (None when no tug was recorded)."""
    csv_path = write_report_csv(records, out_dir, stem)
    tug_csv = write_tug_csv(series, out_dir, stem)
    png_path = csv_path.with_suffix('.png')
    plot_report(records, png_path)
    tug_png = None if tug_csv is None else plot_tug_series(
        series.samples, tug_csv.with_suffix('.png'), slow_ratio, stop_ratio)
    return csv_path, png_path, tug_png


def write_report_csv(records: list[CycleRecord], out_dir: str | Path,
                     stem: str = 'cycle_report') -> Path:
    """Write the table alone, ``stem``.csv in ``out_dir``; returns its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f'{stem}.csv'
    names = [f.name for f in fields(CycleRecord)]
    with io.StringIO(newline='') as f:
        w = csv.DictWriter(f, fieldnames=names)
        w.writeheader()
        for r in records:
            w.writerow({k: (f'{v:.4f}' if isinstance(v, float) else v)
                        for k, v in asdict(r).items()})
        write_text(csv_path, f.getvalue())     # atomic; a planted link is replaced
    return csv_path


def plot_report(records: list[CycleRecord], path: str | Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    sleds = sorted({r.sled_kg for r in records}) or [0.0]
    fig, axes = plt.subplots(2, len(sleds), figsize=(5.5 * len(sleds), 6), squeeze=False,
                             gridspec_kw={'height_ratios': [1, 2.2]}, sharex='col')
    colors = {'walk': '#7fa7d9', 'burrow': '#e0a458', 'tug': '#8cc084'}
    for k, sled in enumerate(sleds):
        rows = [r for r in records if r.sled_kg == sled]
        ax_d, ax_e = axes[0][k], axes[1][k]
        dist = cum = 0.0
        lines = 1
        xs, ds = [0], [0.0]
        for r in rows:
            x = r.cycle
            bottom = cum
            if cum > 0:
                ax_e.bar(x, cum, color='#dddddd', edgecolor='k', linewidth=0.4,
                         label='earlier cycles' if x == rows[1].cycle else None)
            for phase, val in (('walk', r.walk_j), ('burrow', r.burrow_j), ('tug', r.tug_j)):
                ax_e.bar(x, val, bottom=bottom, color=colors[phase], edgecolor='k',
                         linewidth=0.4, label=phase if x == rows[0].cycle else None)
                bottom += val
            cum = bottom
            # a re-burrowed cycle names each gait: one per line, so it stays over its bar
            ax_e.text(x, cum, r.mode.replace('+', ' +\n'), ha='center', va='bottom', fontsize=8)
            lines = max(lines, r.mode.count('+') + 1)
            if r.outcome != 'ok':
                ax_e.plot([x], [cum * 0.5], marker='x', color='red', markersize=14, mew=3)
            dist += r.distance_m
            xs.append(x)
            ds.append(dist)
        ax_d.plot(xs, ds, 'o-', color='k')
        ax_d.set_ylabel('distance walked [m]\n(estimate)')
        ax_d.set_title(f'{1e3 * sled:.0f} g sled')
        ax_e.set_xlabel('cycle')
        ax_e.set_ylabel('cumulated energy [J]')
        ax_e.set_xticks([r.cycle for r in rows] or [1])
        if cum > 0:      # room above the tallest bar for its label
            ax_e.set_ylim(0.0, cum * (1.08 + 0.07 * lines))
        ax_e.legend(loc='upper left', fontsize=8)
        if any(r.outcome != 'ok' for r in rows):
            ax_e.annotate('X: anchor stopped / refused', xy=(0.98, 0.02),
                          xycoords='axes fraction', ha='right', color='red', fontsize=8)
    fig.suptitle('MiniRQuad walk-burrow-tug cycles (energy per phase, cf. paper Fig. 12)')
    save(fig, path)     # layout, atomic write, free


def merged(*groups: list[CycleRecord]) -> list[CycleRecord]:
    return [r for g in groups for r in g if not math.isnan(r.sled_kg)]
