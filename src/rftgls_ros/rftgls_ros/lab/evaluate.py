"""Offline evaluation of pull tests against every prediction method (paper Table I, Fig. 8).

For each test and method:
  - peak pull force: measured max of the load cell (after a 5-sample running median, so one
    spike is not the peak) against the max of the predicted force along the slip trajectory;
  - dz/dx and dthetaB/|dx|: slopes of least-squares lines of z and thetaB against dx, the
    horizontal displacement of p along the pull (dx = x0 - x > 0 as p is dragged toward -x),
    fitted over the common window 0 <= dx <= min(measured, predicted travel, window);
    thetaB slope in deg/mm at the edges (Table I), rad/m inside.
Summary: mean +- standard deviation (ddof 1) of the absolute errors over the tests where the
method gave a value; the count of tests without one is reported next to it, never hidden.

    python -m rftgls_ros.lab.evaluate BAG [BAG ...] [--methods ellipsoid alpha twist-mesh
        direct map] [--map maps/prototype_glass_beads.h5] [--medium NAME|FILE.json]
        [--out-dir DIR]            # writes table.md, results.csv, fig8.png
"""
from __future__ import annotations

import csv
import io
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rftgls_conventions.safe_write import output_folder, write_text
from rftgls_core.charts.figure_io import save
from rftgls_core.cli.main import RftglsParser, cli_contract
from rftgls_core.predictor import Predictor
from rftgls_core.quantities import SLIP_STEP_M, SLIP_TRAVEL_M
from rftgls_node_base.node_main import program_args

from .bag_layout import PullTest, read_pull_test
from .predict import (
    METHODS,
    LabAnchor,
    PredictedPull,
    add_anchor_arguments,
    initial_pose,
    load_anchor,
    load_medium,
    make_predictor,
    medium_from_dict,
    predict_pull,
)

MIN_WINDOW_M = 2e-3          # shorter common travel: no slope is reported
METRICS = (('peak_N', 'F_pull,max (N)', 1.0), ('dz_dx', 'dz/dx', 1.0),
           ('dtheta_dx', 'dthetaB/\\|dx\\| (deg/mm)', math.degrees(1.0) * 1e-3))


def running_median(v: np.ndarray, k: int = 5) -> np.ndarray:
    if v.size < k:
        return v
    pad = k // 2
    w = np.lib.stride_tricks.sliding_window_view(np.pad(v, pad, mode='edge'), k)
    return np.median(w, axis=1)


def slope(dx: np.ndarray, y: np.ndarray, window: float) -> float:
    m = (dx <= window) & np.isfinite(y)
    if m.sum() < 2 or np.ptp(dx[m]) < 0.5 * MIN_WINDOW_M:
        return math.nan
    return float(np.polyfit(dx[m], y[m], 1)[0])


@dataclass
class Measured:
    peak_N: float
    dx: np.ndarray            # (M,) m along the pull
    z: np.ndarray
    theta_b: np.ndarray
    force_dx: np.ndarray      # load cell samples placed on dx by the pose at their time
    force_N: np.ndarray

    @classmethod
    def from_test(cls, test: PullTest) -> 'Measured':
        x0 = initial_pose(test)[0]
        dx = x0 - test.pose[:, 0]
        fdx = np.interp(test.force_t, test.pose_t, dx)
        return cls(float(np.max(running_median(test.tension_N))), dx, test.pose[:, 1],
                   test.pose[:, 2], fdx, test.tension_N)


@dataclass
class Row:
    test_id: str
    method: str
    measured: dict
    predicted: dict
    stop_reason: str

    def error(self, key: str) -> float:
        return abs(self.predicted[key] - self.measured[key])


def compare(test: PullTest, pred: PredictedPull, window: float = 0.04) -> Row:
    meas = Measured.from_test(test)
    x0 = initial_pose(test)[0]
    tr = pred.traj[np.isfinite(pred.traj[:, 1])]
    pdx = x0 - tr[:, 1]
    travel = min(np.nanmax(meas.dx), np.max(pdx) if len(pdx) else 0.0, window)
    if travel < MIN_WINDOW_M:
        ms = ps = (math.nan, math.nan)
    else:
        ms = slope(meas.dx, meas.z, travel), slope(meas.dx, meas.theta_b, travel)
        ps = slope(pdx, tr[:, 2], travel), slope(pdx, tr[:, 3], travel)
    measured = {'peak_N': meas.peak_N, 'dz_dx': ms[0], 'dtheta_dx': ms[1]}
    predicted = {'peak_N': pred.peak_N, 'dz_dx': ps[0], 'dtheta_dx': ps[1]}
    return Row(test.meta.test_id, pred.method, measured, predicted, pred.stop_reason)


def summarise(rows: list[Row], methods: list[str]) -> dict:
    """{method: {metric: (mean, std, n_with_value, n_without)}} of absolute errors (SI)."""
    out = {}
    for m in methods:
        out[m] = {}
        for key, _, _ in METRICS:
            e = np.array([r.error(key) for r in rows if r.method == m])
            v = e[np.isfinite(e)]
            out[m][key] = (float(v.mean()) if v.size else math.nan,
                           float(v.std(ddof=1)) if v.size > 1 else math.nan,
                           int(v.size), int(e.size - v.size))
    return out


def table_markdown(summary: dict, title: str = '') -> str:
    methods = list(summary)
    lines = [f'{title}\n' if title else '',
             '| absolute error (mean ± std) | ' + ' | '.join(methods) + ' |',
             '|---|' + '---|' * len(methods)]
    for key, label, scale in METRICS:
        cells = []
        for m in methods:
            mean, std, n, miss = summary[m][key]
            cell = f'{mean * scale:.3f} ± {std * scale:.3f}' if n else '–'
            cells.append(cell + f' (n={n}' + (f', {miss} none)' if miss else ')'))
        lines.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(line for line in lines if line != '') + '\n'


def plot_fig8(tests: list[PullTest], preds: dict[str, list[PredictedPull]], path: str | Path,
              title: str = '') -> Path:
    """Force, z and thetaB of p against dx (mm), like the paper's Fig. 8: measured solid,
    predictions dashed; an X where a prediction stopped on the plate touching the sand."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    n = len(tests)
    fig, axs = plt.subplots(3, n, figsize=(3.2 * n + 0.8, 7.5), squeeze=False, sharex='col')
    colours = dict(zip(METHODS, ('tab:blue', 'tab:orange', 'tab:green', 'tab:red', 'tab:purple')))
    for j, test in enumerate(tests):
        meas = Measured.from_test(test)
        x0 = initial_pose(test)[0]
        axs[0, j].plot(meas.force_dx * 1e3, meas.force_N, 'k-', lw=1.2, label='measured')
        axs[1, j].plot(meas.dx * 1e3, meas.z * 1e3, 'k-', lw=1.2)
        axs[2, j].plot(meas.dx * 1e3, np.degrees(meas.theta_b), 'k-', lw=1.2)
        for method, plist in preds.items():
            p = plist[j]
            dx = (x0 - p.traj[:, 1]) * 1e3
            kw = dict(ls='--', lw=1.2, color=colours.get(method), label=method)
            axs[0, j].plot(dx, p.traj[:, 4], **kw)
            axs[1, j].plot(dx, p.traj[:, 2] * 1e3, **kw)
            axs[2, j].plot(dx, np.degrees(p.traj[:, 3]), **kw)
            if 'plate' in p.stop_reason and len(dx):
                axs[1, j].plot(dx[-1], p.traj[-1, 2] * 1e3, 'x', color=colours.get(method), ms=8)
        m = test.meta
        tag = ' (synthetic)' if m.synthetic else ''
        axs[0, j].set_title(f'{m.pull}, ({math.degrees(m.initial_state.theta_l1):.0f}°, '
                            f'{math.degrees(m.initial_state.theta_l2):.0f}°){tag}', fontsize=9)
        axs[2, j].set_xlabel('Δx along the pull (mm)')
    axs[0, 0].set_ylabel('F_pull (N)')
    axs[1, 0].set_ylabel('z of p (mm)')
    axs[2, 0].set_ylabel('θB (deg)')
    axs[0, 0].legend(fontsize=7)
    for a in axs.flat:
        a.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    path = Path(path)
    save(fig, path)     # layout, folder, write, free
    return path


def evaluate(tests: list[PullTest], methods: list[str], map_path: str | Path | None = None,
             medium=None, step: float = 1e-3, max_travel: float = 0.04,
             integrator: str = 'heun', progress: bool = True,
             anchor: LabAnchor | None = None
             ) -> tuple[list[Row], dict[str, list[PredictedPull]]]:
    """Predict every test with every method (medium: None = each bag's own medium; anchor:
    None = each bag's own robot, else this description for every bag)."""
    predictors: dict[tuple, Predictor] = {}
    rows: list[Row] = []
    preds: dict[str, list[PredictedPull]] = {m: [] for m in methods}
    jobs = [(t, m) for t in tests for m in methods]
    it = jobs
    if progress:
        from tqdm import tqdm
        it = tqdm(jobs, unit='prediction', file=sys.stderr)
    for test, method in it:
        med = medium if medium is not None else medium_from_dict(test.meta.medium)
        key = (method, test.meta.robot, med)
        if key not in predictors:
            predictors[key] = make_predictor(method, test.meta.robot, med, map_path,
                                             anchor=anchor)
        pred = predict_pull(predictors[key], test, method, step=step, max_travel=max_travel,
                            integrator=integrator, anchor=anchor)
        preds[method].append(pred)
        rows.append(compare(test, pred, window=max_travel))
    return rows, preds


def write_csv(rows: list[Row], path: str | Path) -> None:
    """results.csv, written atomically (safe_write)."""
    fh = io.StringIO(newline='')
    w = csv.writer(fh)
    w.writerow(['test_id', 'method', 'meas_peak_N', 'pred_peak_N', 'meas_dz_dx', 'pred_dz_dx',
                'meas_dtheta_dx_deg_per_mm', 'pred_dtheta_dx_deg_per_mm', 'stop_reason'])
    k = math.degrees(1.0) * 1e-3
    for r in rows:
        w.writerow([r.test_id, r.method, r.measured['peak_N'], r.predicted['peak_N'],
                    r.measured['dz_dx'], r.predicted['dz_dx'],
                    r.measured['dtheta_dx'] * k, r.predicted['dtheta_dx'] * k, r.stop_reason])
    write_text(path, fh.getvalue())


@cli_contract('evaluate')
def main(argv: list[str] | None = None) -> int:
    ap = RftglsParser(prog='python -m rftgls_ros.lab.evaluate',
                                 description='pull tests vs. predictions (Table I, Fig. 8)')
    ap.add_argument('bags', nargs='+')
    ap.add_argument('--methods', nargs='+', default=list(METHODS), choices=METHODS)
    ap.add_argument('--map', default=None, help="HDF5 map for method 'map' "
                    "(default: the robot's shipped map, if built for the bags' medium)")
    ap.add_argument('--medium', default=None,
                    help='preset name or medium JSON (default: each bag\'s own medium)')
    add_anchor_arguments(ap)
    ap.add_argument('--step', type=SLIP_STEP_M.arg, default=1e-3, help='simulation step, m of p')
    ap.add_argument('--max-travel', type=SLIP_TRAVEL_M.arg, default=0.04, help='m')
    ap.add_argument('--integrator', choices=['euler', 'heun'], default='heun')
    ap.add_argument('--out-dir', default='lab_eval')
    args = ap.parse_args(program_args(argv, ap.prog))
    try:
        # The small inputs first, so a bad one is refused before the bags are decoded.
        out = output_folder(args.out_dir, '--out-dir')
        anchor = load_anchor(args.anchor, args.anchor_state)
        medium = load_medium(args.medium) if args.medium else None
        from rftgls_core.maps import resolve_map
        map_path = resolve_map(args.map) if args.map is not None else None
        tests = [read_pull_test(b) for b in args.bags]
        methods = list(args.methods)
        if 'map' in methods and map_path is None:
            # The robot's installed map (never a file in the current directory), and only
            # if it was built for the bags' medium: a map answers for its own medium only.
            from rftgls_core.maps import CapacityMap
            try:
                guess = resolve_map(None, robot=tests[0].meta.robot)
                cmap = CapacityMap.load(guess)
                medium_ok = cmap.medium_name == tests[0].meta.medium.get('name')
                if anchor is not None:   # and it answers for the description (ValueError)
                    cmap.check_description(anchor.sha256)
            except ValueError:   # MapFileError is one
                guess, medium_ok = None, False
            if guess is not None and medium_ok:
                map_path = guess
            else:
                print("evaluate: no --map given and no shipped map for this robot, medium "
                      "(and --anchor); skipping 'map'", file=sys.stderr)
                methods.remove('map')
        rows, preds = evaluate(tests, methods, map_path, medium, args.step, args.max_travel,
                               args.integrator, anchor=anchor)
    except (ValueError, OSError) as exc:
        print(f'evaluate: error: {exc}', file=sys.stderr)
        return 2
    synthetic = any(t.meta.synthetic for t in tests)
    title = (f'{len(tests)} pull tests' + (' (SYNTHETIC data)' if synthetic else '')
             + ': absolute errors in predictions')
    md = table_markdown(summarise(rows, methods), title)
    write_text(out / 'table.md', md)
    write_csv(rows, out / 'results.csv')
    plot_fig8(tests[:4], {m: preds[m][:4] for m in methods}, out / 'fig8.png', title=title)
    print(md)
    print(f'wrote {out / "table.md"}, {out / "results.csv"}, {out / "fig8.png"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
