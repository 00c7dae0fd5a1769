"""examples/anchors: the STL files are what make_anchors.py writes, the
documented commands answer, and the finned stake's own symmetries check the two paths."""
from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import pytest
from tolerances import TWO_SOLVES_RTOL, TWO_SOLVES_TWIST_ATOL

from rftgls_core.cli.main import main
from rftgls_core.geometry.stl import write_stl

FOLDER = Path(__file__).resolve().parents[2] / 'examples' / 'anchors'


def make_anchors():
    spec = importlib.util.spec_from_file_location('make_anchors', FOLDER / 'make_anchors.py')
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_files_are_what_the_script_writes(tmp_path):
    for name, mesh in make_anchors().anchors().items():
        write_stl(tmp_path / f'{name}.stl', mesh, units='mm', name=name)
        assert (tmp_path / f'{name}.stl').read_bytes() == (FOLDER / f'{name}.stl').read_bytes()


def documented_capacity_commands() -> list[list[str]]:
    text = (FOLDER / 'README.md').read_text()
    return [line.split()[1:] for line in text.splitlines()
            if re.match(r'^rftgls capacity ', line)]


@pytest.mark.parametrize('argv', documented_capacity_commands(), ids=lambda a: ' '.join(a[2:4]))
def test_documented_commands_answer(argv, capsys, monkeypatch):
    monkeypatch.chdir(FOLDER)
    assert main(argv) == 0
    res = json.loads(capsys.readouterr().out)
    assert res['status'] == 'ok' and res['capacity_N'] > 0


def stake(capsys, monkeypatch, *extra):
    monkeypatch.chdir(FOLDER)
    assert main(['capacity', '--mesh', 'finned.stl', '--position', '0', '0', '-0.02',
                 '--tether', '0', '0', '-0.02', '--mass', '0.030', '--phi', '30', '--json',
                 *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_stake_is_symmetric_about_its_diagonal_planes(capsys, monkeypatch):
    # A cross of fins: yaw 30 and 60 deg are mirror images about the 45 deg plane (both 6D),
    # yaw 45 deg lies in a symmetry plane (the sagittal reduction answers).
    a, b = stake(capsys, monkeypatch, '--yaw', '30'), stake(capsys, monkeypatch, '--yaw', '60')
    assert a['method'] == b['method'] == 'direct-6d'
    assert a['capacity_N'] == pytest.approx(b['capacity_N'], rel=1e-6)
    assert 'sagittal' in stake(capsys, monkeypatch, '--yaw', '45')['detail']


def test_the_stake_gives_the_same_answer_on_both_paths(capsys, monkeypatch):
    sag = stake(capsys, monkeypatch)
    full = stake(capsys, monkeypatch, '--space', '6d')
    assert full['method'] == 'direct-6d'
    assert full['capacity_N'] == pytest.approx(sag['capacity_N'], rel=1e-6)


def test_the_ellipsoid_description_is_the_mesh_command(capsys, monkeypatch):
    """ellipsoid.yaml at depth -55 mm, tilt -30 deg is the `--mesh` pose of the README table
    (its char_length_m is the --mesh L_c): the same capacity and slip twist."""
    monkeypatch.chdir(FOLDER)
    assert main(['capacity', '--anchor', 'ellipsoid.yaml', '--state', 'depth=-0.055',
                 '--state', 'tilt=-30', '--phi', '45', '--json']) == 0
    d = json.loads(capsys.readouterr().out)
    assert main(['capacity', '--mesh', 'ellipsoid.stl', '--position', '0', '0', '-0.055',
                 '--rpy', '0', '30', '0', '--tether', '0', '0', '-0.055', '--mass', '0.040',
                 '--phi', '45', '--json']) == 0
    m = json.loads(capsys.readouterr().out)
    assert d['status'] == m['status'] == 'ok'
    # the same body placed from a description and from the STL: two solves
    assert d['capacity_N'] == pytest.approx(m['capacity_N'], rel=TWO_SOLVES_RTOL)
    assert d['slip_twist_scaled'] == pytest.approx(m['slip_twist_scaled'],
                                                   abs=TWO_SOLVES_TWIST_ATOL)
