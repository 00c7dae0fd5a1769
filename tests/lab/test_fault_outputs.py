"""Fault campaign of the outputs: a symlink planted at every output path of every tool is
replaced by the new file, and the file it pointed to is left unchanged.

Every writer goes through safe_write (a fresh name in the target folder, fsync, rename over
the target: rename replaces the link itself, docs/design/safe-io.md). Each case plants, at
each path a tool writes, a link to a 'victim' file (a bag folder: a victim folder), runs the
tool in this process and checks the path is now the tool's own regular file (folder) and the
victim's bytes are what they were. Where a tool's computation takes tens of seconds (a
figure's slip simulations, a capacity-over-yaw sweep), the computing function is replaced by
a small stand-in that draws through the same `save`; what is tested is the writing, which is
the tool's own code either way.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rosbags')

from rftgls_core.cli.main import main as rftgls  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
GOOD_BAG = REPO / 'src/rftgls_ros/rftgls_ros/lab/samples/backward_L1-020_L2+020'
ANCHORS = REPO / 'examples' / 'anchors'
DH = ['--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30']
VICTIM = b'the victim: a link at an output path pointed here; must stay unchanged\n'


class Planted:
    """Links at output paths (relative to `root`), each to its own victim outside root."""

    def __init__(self, root: Path, victims: Path, names: list[str], folders: tuple = ()):
        self.root, self.links = root, {}
        for name in names:
            link = root / name
            link.parent.mkdir(parents=True, exist_ok=True)
            victim = victims / (name.replace('/', '__') + '.victim')
            if name in folders:
                victim.mkdir(parents=True)
                (victim / 'inside').write_bytes(VICTIM)
            else:
                victim.write_bytes(VICTIM)
            link.symlink_to(victim, target_is_directory=name in folders)
            self.links[name] = (link, victim, name in folders)

    def problems(self) -> list[str]:
        out = []
        for name, (link, victim, folder) in self.links.items():
            if link.is_symlink():
                out.append(f'{name}: still a link')
            elif not (link.is_dir() if folder else link.is_file()):
                out.append(f'{name}: not written')
            kept = victim
            if folder:
                if sorted(p.name for p in victim.iterdir()) != ['inside']:
                    out.append(f'{name}: files added to the victim folder')
                kept = victim / 'inside'
            if kept.read_bytes() != VICTIM:
                out.append(f'{name}: the victim was overwritten')
        return out


@pytest.fixture
def plant(tmp_path):
    victims = tmp_path / 'victims'
    victims.mkdir()

    def make(names: list[str], folders: tuple = ()) -> Planted:
        return Planted(tmp_path / 'out', victims, names, folders)
    return make


def _ok(code: int, planted: Planted) -> None:
    assert code == 0
    problems = planted.problems()
    assert not problems, problems


# ------------------------------------------------------------------------- rftgls commands
def test_plot(plant):
    p = plant(['p.png'])
    _ok(rftgls(['plot', *DH, '--out', str(p.root / 'p.png')]), p)


def test_plot_scene_and_its_json(plant, monkeypatch):
    from rftgls_core.charts import posed_capacity

    def sweep(solver, posed, phi, yaw, out):   # stands in for the 6D sweep over yaw
        from rftgls_core.charts.figure_io import pyplot, save
        fig = pyplot().figure()
        save(fig, out)
        return {'by_yaw': {'capacity_N': [1.0, 2.0]}}
    monkeypatch.setattr(posed_capacity, 'plot_posed_capacity', sweep)
    p = plant(['a.png', 'a.json'])
    _ok(rftgls(['plot', '--anchor', str(ANCHORS / 'ellipsoid.yaml'), '--state', 'depth=-0.05',
                '--state', 'tilt=-30', '--out', str(p.root / 'a.png')]), p)


def test_simulate_pull_csv_and_plot(plant):
    p = plant(['s.csv', 's.png'])
    _ok(rftgls(['simulate', 'pull', *DH, '--method', 'map', '--max-travel', '0.005',
                '--out', str(p.root / 's.csv'), '--plot', str(p.root / 's.png')]), p)


def test_simulate_burrow_folder(plant):
    """The whole-robot simulation's three files (a short tethered SH burrow)."""
    p = plant(['sim/trajectory.csv', 'sim/summary.json', 'sim/run.png'])
    _ok(rftgls(['simulate', 'burrow', '--mode', 'SH', '--sled', '0.4', '--duration', '2.5',
                '--out', str(p.root / 'sim')]), p)


def test_map_plot(plant):
    p = plant(['m.png'])
    _ok(rftgls(['map', 'plot', 'minirquad', '--n', '20', '--out', str(p.root / 'm.png')]), p)


def test_map_build_and_refine(plant):
    p = plant(['m.h5', 'r.h5'])
    grid = ['--h', '10,20', '--theta-b', '0,10', '--theta-l1=-20,0', '--theta-l2', '0,20',
            '--phi=-20,0', '--pulls', 'backward']
    assert rftgls(['map', 'build', '--robot', 'prototype', '--medium', 'glass_beads', *grid,
                   '--n-twists', '100', '--workers', '1', '--quiet', '--out',
                   str(p.root / 'm.h5')]) == 0
    _ok(rftgls(['map', 'refine', str(p.root / 'm.h5'), '--tol', '0', '--samples', '1',
                '--workers', '1', '--quiet', '--out', str(p.root / 'r.h5')]), p)


def test_map_build_of_a_description(plant):
    p = plant(['d.h5'])
    _ok(rftgls(['map', 'build', '--anchor', str(ANCHORS / 'ellipsoid.yaml'), '--axis',
                'depth=-0.06,-0.05', '--axis', 'tilt=-30,-20', '--phi=0,10', '--n-twists',
                '100', '--method', 'twist-mesh', '--workers', '1', '--quiet', '--out',
                str(p.root / 'd.h5')]), p)


def test_demo_folder(plant):
    p = plant(['demo/limit_surface_DH.png', 'demo/anchors.json'])
    _ok(rftgls(['demo', '--out', str(p.root / 'demo')]), p)


def test_figure_fig10b(plant):
    p = plant(['f.png', 'f.json'])
    _ok(rftgls(['figure', 'fig10b', '--out', str(p.root / 'f.png')]), p)


def test_figure_fig8_both_pulls(plant, monkeypatch):
    from rftgls_core.charts import paper_figures as pf
    from rftgls_core.sim.trajectory import Trajectory, TrajectoryPoint

    def slip(predictor, state, pull, travel, step):   # stands in for a slip simulation
        pts = [TrajectoryPoint(s, -s, 0.02 + 0.1 * s, 0.0, 3.0, 'ok') for s in (0.0, 0.01)]
        return pf.SlipSummary(3.0, 0.1, 0.0, 'travel'), Trajectory(pts, 'travel')
    monkeypatch.setattr(pf, 'slip_summary', slip)
    p = plant(['f8_forward.png', 'f8_backward.png', 'f8.json'])
    _ok(rftgls(['figure', 'fig8', '--out', str(p.root / 'f8.png')]), p)


def test_figure_fig9_and_fig13(plant, monkeypatch):
    from rftgls_core.charts import fig13
    from rftgls_core.charts import paper_figures as pf
    from rftgls_core.charts.figure_io import pyplot, save
    grids = {k: np.ones((5, 5)) for k in ('peak', 'dz_dx', 'dtb')}
    monkeypatch.setattr(pf, 'leg_angle_maps', lambda predictor, progress=None: {
        'forward': grids, 'backward': grids})
    monkeypatch.setattr(fig13, 'fig13_data', lambda method, progress: ({'peak_N': 1.0}, {}))
    monkeypatch.setattr(fig13, 'plot_fig13', lambda data, trajs, out: save(pyplot().figure(),
                                                                          out))
    p = plant(['f9.png', 'f9.json', 'f13.png', 'f13.json'])
    assert rftgls(['figure', 'fig9', '--out', str(p.root / 'f9.png')]) == 0
    _ok(rftgls(['figure', 'fig13', '--out', str(p.root / 'f13.png')]), p)


def test_chart_speed_accuracy_and_agreement(plant):
    p = plant(['c.png', 'c.csv', 'c.json', 'ag.json'])
    assert rftgls(['chart', 'speed-accuracy', '--quick', '--states', '1', '--robots',
                   'prototype', '--out', str(p.root / 'c.png')]) == 0
    _ok(rftgls(['chart', 'agreement', '--states', '1', '--robots', 'prototype',
                '--reference-twists', '2000', '--out', str(p.root / 'ag.json')]), p)


def test_calibrate_medium_and_its_plot(plant, tmp_path):
    csv = tmp_path / 'pen.csv'
    csv.write_text('depth_m,force_N\n0.01,0.5\n0.02,1.0\n0.03,1.5\n')
    p = plant(['med.json', 'med_fit.png'])
    _ok(rftgls(['calibrate', '--penetration', str(csv), '--plate-area', '1e-4', '--out',
                str(p.root / 'med.json')]), p)


# ------------------------------------------------------------------------- lab tools
def test_lab_eval_out_dir(plant):
    from rftgls_ros.lab.evaluate import main
    p = plant(['ev/table.md', 'ev/results.csv', 'ev/fig8.png'])
    _ok(main([str(GOOD_BAG), '--methods', 'map', '--out-dir', str(p.root / 'ev')]), p)


def test_lab_synthetic_bag_folder(plant):
    from rftgls_ros.lab.synthetic import main
    name = 'syn/backward_L1-020_L2+020'
    p = plant([name], folders=(name,))
    _ok(main(['--out-dir', str(p.root / 'syn'), '--config=-20,20,backward', '--step', '0.002',
              '--max-travel', '0.004', '--integrator', 'euler']), p)


def test_lab_track_bag_writer(plant):
    """rftgls_lab_track writes its bag with write_pull_test, here given a read test."""
    from rftgls_ros.lab.bag_layout import read_pull_test, write_pull_test
    p = plant(['tracked'], folders=('tracked',))
    write_pull_test(p.root / 'tracked', read_pull_test(GOOD_BAG))
    _ok(0, p)
    assert read_pull_test(p.root / 'tracked').meta.test_id


# ------------------------------------------------------------------------- behavior_demo
def test_behavior_reports_and_logs(plant):
    from rftgls_ros.behavior.report import CycleRecord, read_csv, write_report
    from rftgls_ros.behavior.tug_series import TugSeries, write_tug_series
    from rftgls_ros.demo import Stack
    p = plant(['r/cycle_report.csv', 'r/cycle_report.png', 'r/c1_tug.csv', 'r/c1_tug.png',
               'r/logs/probe.log'])
    rec = CycleRecord(0.4, 1, 'DH', 'ok', *([1.0] * 12))
    write_report([rec, rec], p.root / 'r')
    series = TugSeries()
    for k in range(5):
        series.add(0.1 * k, 1.0 + k, 5.0, 4.0, 'ok', 'tug')
    write_tug_series(series, p.root / 'r', 'c1')
    stack = Stack({}, p.root / 'r' / 'logs')
    stack.start('probe', [sys.executable, '-c', 'print("logged")'])
    stack.procs[0][1].wait(30)
    stack.close()
    _ok(0, p)
    assert read_csv(p.root / 'r' / 'cycle_report.csv')[0].mode == 'DH'
    assert (p.root / 'r' / 'logs' / 'probe.log').read_text().strip() == 'logged'


def test_simulator_record(plant):
    from minirquad_sim.main import main
    p = plant(['rec.jsonl'])
    _ok(main(['--ground', 'table', '--duration', '0.3', '--record', str(p.root / 'rec.jsonl')]),
        p)
    assert json.loads((p.root / 'rec.jsonl').read_text().splitlines()[0])


# ------------------------------------------------------------------------- library writers
def test_stl_and_robot_description_writers(plant):
    from rftgls_core.description_writer import write_robot_description
    from rftgls_core.geometry.shapes import c_leg
    from rftgls_core.geometry.stl import read_stl, write_stl
    p = plant(['leg.stl', 'desc/minirquad.urdf', 'desc/minirquad.yaml', 'desc/c_leg.stl'])
    write_stl(p.root / 'leg.stl', c_leg(arc_diameter=0.09, thickness=0.005, width=0.01,
                                        n_arc=8), units='mm')
    write_robot_description('minirquad', p.root / 'desc')
    _ok(0, p)
    assert len(read_stl(p.root / 'leg.stl').faces) > 0


def test_a_failed_writer_leaves_the_target_and_no_temporary(tmp_path):
    from rftgls_conventions.safe_write import atomic_write
    target = tmp_path / 'keep.csv'
    target.write_bytes(b'old\n')
    with pytest.raises(RuntimeError):
        with atomic_write(target) as tmp:
            tmp.write_bytes(b'half')
            raise RuntimeError('the writer failed')
    assert target.read_bytes() == b'old\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['keep.csv']
