"""Fault campaign of the file options: a FIFO, /dev/zero, a directory and an oversized file
given to every file option of every tool end in ONE line on stderr, exit 2, within 2 s, with
nothing written.

Why each is dangerous (docs/design/safe-io.md): a FIFO blocks a reader forever, /dev/zero
feeds it until memory runs out, a directory or an oversized file is a mistake the reader must
name. The oversized files are sparse (the size limit + 1 byte, no disk used). Beside the
options themselves, the files a description names (URDF, xacro includes, xacro's load_yaml,
meshes) and the files inside a bag folder (storage, metadata.yaml) get the same four.

The cases run in one subprocess (tests/fault_runner.py): each program's main(argv) in-process,
under a memory limit and a watchdog that reports and releases a reader stuck on a FIFO. The
2 s bound is measured per call after one untimed warm-up call of the same program (imports
are not the reader's time; an interpreter start alone takes seconds on the test machines).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import pytest

pytest.importorskip('rosbags')

from rftgls_conventions.safe_read import MAX_BYTES  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / 'src/rftgls_ros/rftgls_ros/lab/samples'
GOOD_BAG = SAMPLES / 'backward_L1-020_L2+020'
ANCHORS = REPO / 'examples' / 'anchors'
RUNNER = REPO / 'tests' / 'fault_runner.py'
HOSTILE = ('fifo', 'dev_zero', 'directory', 'oversized')
LIMIT_S = 2.0

RFTGLS = 'rftgls_core.cli.main'
EVAL, CAL = 'rftgls_ros.lab.evaluate', 'rftgls_ros.lab.calibrate'
SYN, TRACK = 'rftgls_ros.lab.synthetic', 'rftgls_ros.lab.aruco_tracking'
REPLAY, DEMO = 'rftgls_ros.lab.replay', 'rftgls_ros.demo'
SIM = 'minirquad_sim.main'
DH = ['--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30']
BODY = ['--position', '0', '0', '-0.05', '--tether', '0', '0', '-0.05', '--mass', '0.05']
TWIST = ['--twist', '1', '0', '0', '0', '0', '0']


def hostile(d: Path, what: str, kind: str, suffix: str, tag: str = '') -> Path:
    """A hostile stand-in for a file of `kind` named with `suffix` (tag: a unique name part)."""
    if what == 'dev_zero':
        return Path('/dev/zero')
    p = d / f'{what}{tag}_{kind}{suffix}'
    if what == 'fifo':
        os.mkfifo(p)
    elif what == 'directory':
        p.mkdir()
    else:
        with open(p, 'wb') as fh:
            fh.truncate(MAX_BYTES[kind] + 1)       # sparse: no disk used
    return p


def options(g: dict[str, str]) -> list[tuple[str, str, list[str], str, str]]:
    """(name, module, argv with '{}' for the file, kind, suffix) of every file option."""
    png, csv, h5, js, out_dir, bag = g['png'], g['csv'], g['h5'], g['json'], g['dir'], g['bag']
    return [
        ('rftgls wrench --mesh', RFTGLS, ['wrench', '--mesh', '{}', *TWIST], 'mesh', '.stl'),
        ('rftgls wrench --medium', RFTGLS, ['wrench', '--mesh', g['stl'], *TWIST, '--medium',
                                            '{}'], 'medium', '.json'),
        ('rftgls capacity --mesh', RFTGLS, ['capacity', '--mesh', '{}', *BODY], 'mesh', '.stl'),
        ('rftgls capacity --medium', RFTGLS, ['capacity', *DH, '--medium', '{}'], 'medium',
         '.json'),
        ('rftgls capacity --anchor', RFTGLS, ['capacity', '--anchor', '{}'], 'description',
         '.yaml'),
        ('rftgls capacity --map', RFTGLS, ['capacity', *DH, '--method', 'map', '--map', '{}'],
         'map', '.h5'),
        ('rftgls plot --mesh', RFTGLS, ['plot', '--mesh', '{}', *BODY, '--out', png], 'mesh',
         '.stl'),
        ('rftgls plot --medium', RFTGLS, ['plot', *DH, '--medium', '{}', '--out', png],
         'medium', '.json'),
        ('rftgls plot --anchor', RFTGLS, ['plot', '--anchor', '{}', '--out', png],
         'description', '.yaml'),
        ('rftgls simulate --mesh', RFTGLS, ['simulate', 'pull', '--mesh', '{}', *BODY, '--out',
                                            csv], 'mesh', '.stl'),
        ('rftgls simulate --medium', RFTGLS, ['simulate', 'pull', *DH, '--medium', '{}',
                                              '--out', csv], 'medium', '.json'),
        ('rftgls simulate --map', RFTGLS, ['simulate', 'pull', *DH, '--method', 'map', '--map',
                                           '{}', '--out', csv], 'map', '.h5'),
        ('rftgls map info', RFTGLS, ['map', 'info', '{}'], 'map', '.h5'),
        ('rftgls map accuracy', RFTGLS, ['map', 'accuracy', '{}', '--quiet'], 'map', '.h5'),
        ('rftgls map accuracy --anchor', RFTGLS, ['map', 'accuracy', g['dmap'], '--anchor',
                                                  '{}', '--quiet'], 'description', '.yaml'),
        ('rftgls map refine', RFTGLS, ['map', 'refine', '{}', '--out', h5, '--quiet'], 'map',
         '.h5'),
        ('rftgls map refine --anchor', RFTGLS, ['map', 'refine', g['dmap'], '--anchor', '{}',
                                                '--out', h5, '--quiet'], 'description', '.yaml'),
        ('rftgls map plot', RFTGLS, ['map', 'plot', '{}', '--out', png], 'map', '.h5'),
        ('rftgls map build --anchor', RFTGLS, ['map', 'build', '--anchor', '{}', '--out', h5,
                                               '--quiet', '--workers', '1'], 'description',
         '.yaml'),
        ('rftgls map build --medium', RFTGLS, ['map', 'build', '--robot', 'minirquad',
                                               '--medium', '{}', '--out', h5, '--quiet'],
         'medium', '.json'),
        ('rftgls figure --medium', RFTGLS, ['figure', 'fig10b', '--medium', '{}', '--out', png],
         'medium', '.json'),
        ('rftgls calibrate BAG', RFTGLS, ['calibrate', '{}', '--out', js], 'bag', '.mcap'),
        ('rftgls calibrate --penetration', RFTGLS, ['calibrate', '--penetration', '{}',
                                                    '--plate-area', '1e-3', '--out', js],
         'csv', '.csv'),
        ('rftgls calibrate --anchor', RFTGLS, ['calibrate', str(GOOD_BAG), '--anchor', '{}',
                                               '--out', js], 'description', '.yaml'),
        ('lab_eval BAG', EVAL, ['{}', '--out-dir', out_dir], 'bag', '.mcap'),
        ('lab_eval --map', EVAL, [str(GOOD_BAG), '--methods', 'map', '--map', '{}',
                                  '--out-dir', out_dir], 'map', '.h5'),
        ('lab_eval --medium', EVAL, [str(GOOD_BAG), '--medium', '{}', '--out-dir', out_dir],
         'medium', '.json'),
        ('lab_eval --anchor', EVAL, [str(GOOD_BAG), '--anchor', '{}', '--out-dir', out_dir],
         'description', '.yaml'),
        ('lab_calibrate BAG', CAL, ['{}', '--out', js], 'bag', '.mcap'),
        ('lab_calibrate --penetration', CAL, ['--penetration', '{}', '--plate-area', '1e-3',
                                              '--out', js], 'csv', '.csv'),
        ('lab_calibrate --anchor', CAL, [str(GOOD_BAG), '--anchor', '{}', '--out', js],
         'description', '.yaml'),
        ('lab_synthetic --anchor', SYN, ['--out-dir', out_dir, '--anchor', '{}'],
         'description', '.yaml'),
        ('lab_track --video', TRACK, ['--video', '{}', '--camera', g['camera'], '--meta',
                                      g['meta'], '--out', bag], 'video', '.mp4'),
        ('lab_track --camera', TRACK, ['--images', g['frames'], '--camera', '{}', '--meta',
                                       g['meta'], '--out', bag], 'calibration', '.json'),
        ('lab_track --meta', TRACK, ['--images', g['frames'], '--camera', g['camera'],
                                     '--meta', '{}', '--out', bag], 'calibration', '.json'),
        ('lab_track --bag-in', TRACK, ['--images', g['frames'], '--camera', g['camera'],
                                       '--bag-in', '{}', '--out', bag], 'bag', '.mcap'),
        ('lab_replay BAG', REPLAY, ['{}', '--wait-subscribers', '0'], 'bag', '.mcap'),
        ('lab_replay --anchor', REPLAY, [str(GOOD_BAG), '--anchor', '{}'], 'description',
         '.yaml'),
        ('behavior_demo --params', DEMO, ['--params', '{}', '--out', out_dir], 'params',
         '.yaml'),
        ('minirquad_sim --anchor', SIM, ['--anchor', '{}', '--duration', '0.1'],
         'description', '.yaml'),
    ]


def inner_files(d: Path, what: str) -> list[tuple[str, str, list[str], Path]]:
    """Files named inside other files: a description's URDF, mesh, xacro include and xacro
    load_yaml; a bag folder's storage file and metadata.yaml; a frame of --images. Each
    (name, module, argv, the hostile file) with the outer file made here."""
    out = []
    base = d / f'inner_{what}'
    base.mkdir()
    yaml_text = (ANCHORS / 'ellipsoid.yaml').read_text()
    urdf_text = (ANCHORS / 'ellipsoid.urdf').read_text()
    shutil.copy(ANCHORS / 'ellipsoid.stl', base / 'ellipsoid.stl')
    for role, kind, suffix in (('urdf', 'urdf', '.urdf'), ('mesh', 'mesh', '.stl'),
                               ('include', 'urdf', '.xacro'), ('load_yaml', 'description',
                                                               '.yaml')):
        bad = hostile(base, what, kind, suffix, role) if what != 'oversized' else \
            _oversized(base, role, kind, suffix)
        # a link inside the description's folder to /dev/zero: the allow-list sees through it
        name = bad.name if what != 'dev_zero' else _link(base, role, suffix).name
        urdf = f'{role}.urdf'
        if role == 'urdf':
            desc_urdf = name
        elif role == 'mesh':
            (base / urdf).write_text(urdf_text.replace('ellipsoid.stl', name))
            desc_urdf = urdf
        else:
            body = (f'<xacro:include filename="{name}"/>' if role == 'include' else
                    f'<link name="y${{len(xacro.load_yaml(\'{name}\'))}}"/>')
            desc_urdf = f'{role}.urdf.xacro'
            (base / desc_urdf).write_text(urdf_text.replace(
                '<robot name="ellipsoid_anchor">',
                '<robot name="ellipsoid_anchor" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                + body))
        yml = base / f'{role}.yaml'
        yml.write_text(yaml_text.replace('urdf: ellipsoid.urdf', f'urdf: {desc_urdf}'))
        out.append((f'description {role} ({what})', RFTGLS,
                    ['capacity', '--anchor', str(yml), '--state', 'depth=-0.05', '--state',
                     'tilt=0'], bad))
    for role in ('storage', 'metadata'):
        bag = base / f'bag_{role}'
        shutil.copytree(GOOD_BAG, bag)
        target = bag / (f'{GOOD_BAG.name}.mcap' if role == 'storage' else 'metadata.yaml')
        target.unlink()
        kind = 'bag' if role == 'storage' else 'bag_metadata'
        if what == 'dev_zero':
            target.symlink_to('/dev/zero')
        elif what == 'fifo':
            os.mkfifo(target)
        elif what == 'directory':
            target.mkdir()
        else:
            with open(target, 'wb') as fh:
                fh.truncate(MAX_BYTES[kind] + 1)
        out.append((f'bag {role} ({what})', CAL, [str(bag), '--out', str(d / 'never.json')],
                    target))
    frames = base / 'frames'
    frames.mkdir()
    frame = frames / 'f0000.png'
    if what == 'dev_zero':
        frame.symlink_to('/dev/zero')
    elif what == 'fifo':
        os.mkfifo(frame)
    elif what == 'directory':
        frame.mkdir()
    else:
        with open(frame, 'wb') as fh:
            fh.truncate(MAX_BYTES['image'] + 1)
    out.append((f'lab_track frame ({what})', TRACK,
                ['--images', str(frames), '--camera', '{camera}', '--meta', '{meta}', '--out',
                 str(d / 'never_bag')], frame))
    return out


def _oversized(d: Path, role: str, kind: str, suffix: str) -> Path:
    p = d / f'oversized_{role}{suffix}'
    with open(p, 'wb') as fh:
        fh.truncate(MAX_BYTES[kind] + 1)
    return p


def _link(d: Path, role: str, suffix: str) -> Path:
    p = d / f'zero_{role}{suffix}'
    p.symlink_to('/dev/zero')
    return p


@pytest.fixture(scope='module')
def good(tmp_path_factory) -> dict[str, str]:
    """The good inputs the cases need besides the hostile one, and output names that must
    stay absent."""
    from rftgls_core.cli.main import main
    from rftgls_ros.lab.bag_layout import CameraCalibration, read_metadata
    d = tmp_path_factory.mktemp('good')
    dmap = d / 'described.h5'
    assert main(['map', 'build', '--anchor', str(ANCHORS / 'ellipsoid.yaml'), '--axis',
                 'depth=-0.06,-0.05', '--axis', 'tilt=-30,-20', '--phi=0,10', '--n-twists',
                 '100', '--method', 'twist-mesh', '--workers', '1', '--quiet', '--out',
                 str(dmap)]) == 0
    (d / 'camera.json').write_text(json.dumps(asdict(CameraCalibration.simple(640, 480, 600.0))))
    (d / 'meta.json').write_text(read_metadata(GOOD_BAG).to_json())
    (d / 'frames').mkdir()
    out = d / 'out'
    return {'stl': str(ANCHORS / 'ellipsoid.stl'), 'dmap': str(dmap),
            'camera': str(d / 'camera.json'), 'meta': str(d / 'meta.json'),
            'frames': str(d / 'frames'), 'png': str(out / 'x.png'), 'csv': str(out / 'x.csv'),
            'h5': str(out / 'x.h5'), 'json': str(out / 'x.json'), 'dir': str(out / 'dir'),
            'bag': str(out / 'bag'), 'out': str(out)}


def run_campaign(cases: list[dict]) -> dict:
    env = dict(os.environ, MPLBACKEND='Agg', RFTGLS_DEBUG='')
    res = subprocess.run([sys.executable, str(RUNNER)], input=json.dumps(
        {'cases': cases, 'timeout_s': 10.0}), capture_output=True, text=True, timeout=900,
        env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def judge(name: str, r: dict | None, must: str) -> str | None:
    """None when the case ended as the contract says; else what went wrong."""
    if r is None:
        return 'not run (an earlier case hung)'
    lines = [ln for ln in r['err'].splitlines() if ln.strip()]
    if r['code'] != 2:
        return f'code {r["code"]}, stderr {r["err"][-300:]!r}'
    if len(lines) != 1 or 'Traceback' in r['err']:
        return f'{len(lines)} stderr lines: {r["err"][-400:]!r}'
    if r['out'].strip():
        return f'printed {r["out"][:200]!r}'
    if r['seconds'] > LIMIT_S:
        return f'{r["seconds"]:.2f} s > {LIMIT_S} s'
    if must not in lines[0]:
        return f'error line does not name {must!r}: {lines[0]!r}'
    return None


def test_every_file_option_refuses_hostile_files_in_one_line(good, tmp_path):
    cases, must = [], {}
    for what in HOSTILE:
        d = tmp_path / what
        d.mkdir()
        for i, (name, module, argv, kind, suffix) in enumerate(options(good)):
            bad = hostile(d, what, kind, suffix, f'{i:02d}')
            key = f'{name} ({what})'
            cases.append({'name': key, 'module': module,
                          'argv': [str(bad) if a == '{}' else a for a in argv],
                          'fifos': [str(bad)] if what == 'fifo' else []})
            must[key] = bad.name
        for key, module, argv, bad in inner_files(d, what):
            argv = [good['camera'] if a == '{camera}' else good['meta'] if a == '{meta}'
                    else a for a in argv]
            cases.append({'name': key, 'module': module, 'argv': argv,
                          'fifos': [str(bad)] if what == 'fifo' else []})
            must[key] = bad.name
    assert len(cases) == 4 * (len(options(good)) + 7), len(cases)
    results = run_campaign(cases)
    failures = {k: p for k in must if (p := judge(k, results.get(k), must[k]))}
    assert not failures, '\n'.join(f'{k}: {v}' for k, v in failures.items())
    assert not os.path.lexists(good['out']), sorted(os.listdir(good['out']))
