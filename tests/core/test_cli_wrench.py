"""`rftgls wrench` contract: JSON keys, agreement with the engine, clean errors (exit 2)."""
import json
import subprocess
import sys

import numpy as np
import pytest

from rftgls_core.geometry.shapes import plate
from rftgls_core.geometry.stl import write_stl

CLI = [sys.executable, '-m', 'rftgls_core.cli.main']


def run(*args):
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=120)


@pytest.fixture(scope='module')
def plate_stl(tmp_path_factory):
    path = tmp_path_factory.mktemp('stl') / 'plate.stl'
    write_stl(path, plate(0.02, 0.02, 0.002), units='mm')  # 20 x 20 x 2 mm
    return path


def test_plate_pushed_down_json(plate_stl):
    out = run('wrench', '--mesh', str(plate_stl), '--position', '0', '0', '-0.05',
              '--twist', '0', '0', '-1', '0', '0', '0', '--xi-n', '3.771e5', '--mu-surf', '0.4',
              '--json')
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    assert set(res) == {'force_N', 'moment_Nm', 'facets_total', 'facets_active', 'model',
                        'medium'}
    # Bottom face: 0.875 xi_n A d at 5.1 cm depth
    # (docs/design/models-rft.md 4.8 scaling: 6.60 N at 5 cm);
    # the four thin side walls slide edge-on and add a little friction-capped stress.
    assert res['force_N'][2] == pytest.approx(6.60 * 0.051 / 0.05, rel=0.03)
    assert res['model'] == 'agarwal' and res['facets_active'] == res['facets_total']


def test_pitched_plate_and_reference_point(plate_stl):
    base = ['wrench', '--mesh', str(plate_stl), '--position', '0.01', '0', '-0.04', '--rpy', '0',
            '30', '0', '--medium', 'm90_sand', '--json']
    a = json.loads(run(*base, '--twist', '1', '0', '0', '0', '0', '0').stdout)
    b = json.loads(run(*base, '--twist', '1', '0', '0', '0', '0', '0',
                       '--ref', '0', '0', '0').stdout)
    assert np.allclose(a['force_N'], b['force_N'])
    # moment about the origin = moment about the mesh origin + r x F
    r = np.array([0.01, 0, -0.04])
    assert np.allclose(b['moment_Nm'], np.array(a['moment_Nm']) + np.cross(r, a['force_N']),
                       atol=1e-9)


@pytest.mark.parametrize('args, message', [
    (['--twist', 'nan', '0', '0', '0', '0', '0'], 'must be finite'),
    (['--twist', '0', '0', '0', '0', '0', '0'], 'invalid_input'),
    (['--twist', '1e-200', '0', '0', '0', '0', '-1e-200'], 'invalid_input'),
    (['--twist', '1', '0', '0', '0', '0', '0', '--medium', 'mud'], 'unknown medium'),
])
def test_bad_input_exits_2_with_a_message(plate_stl, args, message):
    out = run('wrench', '--mesh', str(plate_stl), *args)
    assert out.returncode == 2
    assert message in out.stderr and 'Traceback' not in out.stderr


def test_malformed_stl_exits_2(tmp_path):
    bad = tmp_path / 'bad.stl'
    bad.write_bytes(b'\x00' * 80 + b'\x05\x00\x00\x00' + b'\x01' * 30)  # truncated binary
    out = run('wrench', '--mesh', str(bad), '--twist', '1', '0', '0', '0', '0', '0')
    assert out.returncode == 2 and 'bad.stl' in out.stderr and 'Traceback' not in out.stderr
    missing = run('wrench', '--mesh', str(tmp_path / 'nope.stl'), '--twist', '1', '0', '0', '0',
                  '0', '0')
    assert missing.returncode == 2 and 'Traceback' not in missing.stderr


def test_inward_wound_stl_is_repaired(plate_stl, tmp_path):
    flipped = tmp_path / 'flipped.stl'
    write_stl(flipped, plate(0.02, 0.02, 0.002).flipped(), units='mm')
    common = ['--position', '0', '0', '-0.05', '--twist', '0.2', '0', '-1', '0', '0', '0',
              '--medium', 'glass_beads', '--json']
    good = json.loads(run('wrench', '--mesh', str(plate_stl), *common).stdout)
    fixed = run('wrench', '--mesh', str(flipped), *common)
    assert fixed.returncode == 0, fixed.stderr
    assert np.allclose(json.loads(fixed.stdout)['force_N'], good['force_N'], rtol=1e-9)
