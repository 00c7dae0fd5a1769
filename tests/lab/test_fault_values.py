"""Fault campaign of the command-line values: every class of value outside its quantity's
physical range (angles, twists, media parameters, masses, positions, lengths and rates) and
every state variable a command does not have is refused in one line, exit 2, and nothing is
answered (stdout stays empty).

The ranges are rftgls_core/quantities.py (their reasons: docs/design/safe-io.md, "Ranges").
Values are never wrapped or clipped before the check: wrapped first, `--phi 1e308` would
look like any other angle and answer `ok` with a capacity. Each class has values far outside
(1e308), just outside the range, and non-finite ones, so a check that only caught overflow
would fail.
"""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip('rosbags')

from rftgls_core.cli.main import main as rftgls  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
ANCHOR = str(REPO / 'examples' / 'anchors' / 'ellipsoid.yaml')
STL = str(REPO / 'examples' / 'anchors' / 'ellipsoid.stl')
DH = ['--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30']
BODY = ['--position', '0', '0', '-0.05', '--tether', '0', '0', '-0.05', '--mass', '0.05']
CAP = ['capacity', *DH, '--json']


def wrench(*twist: str) -> list[str]:
    return ['wrench', '--mesh', STL, '--twist', *twist, '--json']


def body(**change: str) -> list[str]:
    """capacity --mesh with one of its body options changed."""
    out = ['capacity', '--mesh', STL, '--json']
    opts = {'--position': ['0', '0', '-0.05'], '--tether': ['0', '0', '-0.05'],
            '--mass': ['0.05'], '--com': None, '--rpy': None}
    for k, v in change.items():
        opts['--' + k] = v.split()
    for k, v in opts.items():
        if v is not None:
            out += [k, *v]
    return out


CASES = {
    # angles (deg at the edge)
    'phi 1e308': CAP + ['--phi', '1e308'],
    'phi 100': CAP + ['--phi', '100'],
    'phi -90.5': CAP + ['--phi', '-90.5'],
    'phi inf': CAP + ['--phi', 'inf'],
    'theta-b 1e308': ['capacity', '--h', '0.034', '--theta-b', '1e308', '--theta-l1', '-40',
                      '--theta-l2', '30'],
    'theta-l1 6.28e6 deg': ['capacity', '--h', '0.034', '--theta-b', '5', '--theta-l1',
                            '6.28e6', '--theta-l2', '30'],
    'theta-l2 361': ['capacity', '--h', '0.034', '--theta-b', '5', '--theta-l1', '-40',
                     '--theta-l2', '361'],
    'rpy 1e308': body(rpy='0 1e308 0'),
    'yaw 1e308': ['capacity', *DH, '--yaw', '1e308'],
    'yaw 181': ['capacity', *DH, '--yaw', '181'],
    'map plot phi 1e308': ['map', 'plot', 'minirquad', '--phi', '1e308', '--out', 'x.png'],
    'map plot theta-b 1e308': ['map', 'plot', 'minirquad', '--theta-b', '1e308', '--out',
                               'x.png'],
    'map build grid angle': ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                             '--theta-l1=-1e308,0', '--out', 'x.h5'],
    'map build grid phi': ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                           '--phi=-100,0', '--out', 'x.h5'],
    'map build grid nan': ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                           '--theta-b', 'nan,0', '--out', 'x.h5'],
    'map build grid step': ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                            '--h=0:1e-300:1e308', '--out', 'x.h5'],
    'map build anchor axis': ['map', 'build', '--anchor', ANCHOR, '--axis', 'tilt=-1e308,0',
                              '--out', 'x.h5'],
    'figure l1 1e308': ['figure', 'fig8', '--l1', '1e308', '--out', 'x.png'],
    # twists (m/s, rad/s)
    'twist 1e308': wrench('1e308', '1e308', '0', '0', '0', '0'),
    'twist 2 m/s': wrench('2', '0', '0', '0', '0', '0'),
    'twist w 1e308': wrench('0', '0', '0', '0', '1e308', '0'),
    'twist w 101 rad/s': wrench('0', '0', '0', '101', '0', '0'),
    'twist nan': wrench('nan', '0', '0', '0', '0', '0'),
    # media
    'xi-n 1e308': CAP + ['--xi-n', '1e308'],
    'xi-n 10': CAP + ['--xi-n', '10'],
    'zeta 1e308': CAP + ['--zeta', '1e308'],
    'mu-surf 1e308': CAP + ['--xi-n', '4e5', '--mu-surf', '1e308'],
    'mu-surf -0.1': CAP + ['--xi-n', '4e5', '--mu-surf', '-0.1'],
    'wrench xi-n 1e308': wrench('1', '0', '0', '0', '0', '0') + ['--xi-n', '1e308'],
    # masses
    'mass 1e308': body(mass='1e308'),
    'mass -1': body(mass='-1'),
    'mass 1000 kg': body(mass='1000'),
    # positions and lengths
    'position 1e308': body(position='0 0 1e308'),
    'tether 1e308': body(tether='1e308 0 0'),
    'com 1e308': body(com='0 0 1e308'),
    'ref 1e308': wrench('1', '0', '0', '0', '0', '0') + ['--ref', '0', '0', '1e308'],
    'h 1e308': ['capacity', '--h', '1e308', '--theta-b', '5', '--theta-l1', '-40',
                '--theta-l2', '30'],
    'map plot h 1e308': ['map', 'plot', 'minirquad', '--h', '1e308', '--out', 'x.png'],
    'simulate step 1e308': ['simulate', 'pull', *DH, '--step', '1e308', '--out', 'x.csv'],
    'simulate speed 1e308': ['simulate', 'pull', *DH, '--speed', '1e308', '--out', 'x.csv'],
    'simulate travel 1e308': ['simulate', 'pull', *DH, '--max-travel', '1e308', '--out',
                              'x.csv'],
    'burrow retract 1e308': ['simulate', 'burrow', '--retract', '1e308', '0', '--final', '0',
                             '0'],
    'burrow speed 1e308': ['simulate', 'burrow', '--mode', 'SH', '--speed', '1e308'],
    'burrow dt 1e308': ['simulate', 'burrow', '--mode', 'SH', '--dt', '1e308'],
    'burrow stall torque -1': ['simulate', 'burrow', '--mode', 'SH', '--stall-torque', '-1'],
    'burrow sled 1e308 kg': ['simulate', 'burrow', '--mode', 'SH', '--sled', '1e308'],
    'walk duration 1e308': ['simulate', 'walk', '--duration', '1e308'],
    'walk period nan': ['simulate', 'walk', '--period', 'nan'],
    'walk duty 2': ['simulate', 'walk', '--duty', '2'],
    'sensitivity modes XX': ['simulate', 'sensitivity', '--out', 'o', '--modes', 'XX'],
    'sensitivity sled 1e308 kg': ['simulate', 'sensitivity', '--out', 'o', '--sled', '1e308'],
    'figure sled friction 1e308': ['figure', 'fig10b', '--sled-friction', '1e308', '--out',
                                   'x.png'],
    'map refine tol 1e308': ['map', 'refine', 'minirquad', '--tol', '1e308', '--out', 'x.h5'],
    'calibrate plate area 1e308': ['calibrate', '--penetration', 'p.csv', '--plate-area',
                                   '1e308'],
    # state variables a command does not have
    'state x=1 with a robot': CAP + ['--state', 'x=1'],
    'state with a mesh': body() + ['--state', 'depth=-0.05'],
    'state unknown of an anchor': ['capacity', '--anchor', ANCHOR, '--state', 'depth=-0.05',
                                   '--state', 'tilt=0', '--state', 'x=1', '--json'],
    'simulate of an anchor': ['simulate', 'pull', '--anchor', ANCHOR, '--state', 'depth=-0.05',
                              '--state', 'tilt=0', '--out', 'x.csv'],
    'state 1e308 of an anchor': ['capacity', '--anchor', ANCHOR, '--state', 'depth=-0.05',
                                 '--state', 'tilt=1e308', '--json'],
}

LAB = {
    'synthetic xi-n 1e308': ('rftgls_ros.lab.synthetic', ['--out-dir', 'o', '--xi-n', '1e308']),
    'synthetic phi 1e308': ('rftgls_ros.lab.synthetic', ['--out-dir', 'o', '--phi', '1e308']),
    'synthetic config angle': ('rftgls_ros.lab.synthetic', ['--out-dir', 'o',
                                                            '--config=1e308,0,backward']),
    'evaluate step 1e308': ('rftgls_ros.lab.evaluate', ['b', '--step', '1e308']),
    'calibrate sigma 1e308': ('rftgls_ros.lab.calibrate', ['b', '--sigma-pull', '1e308']),
    'replay rate 1e308': ('rftgls_ros.lab.replay', ['b', '--rate', '1e308']),
    'track fps 1e308': ('rftgls_ros.lab.aruco_tracking', ['--images', 'i', '--camera', 'c',
                                                          '--meta', 'm', '--out', 'o',
                                                          '--fps', '1e308']),
    'tracking noise 1e308': ('rftgls_ros.lab.tracking_accuracy', ['--noise', '1e308']),
    'behavior_demo sled 1e308 kg': ('rftgls_ros.demo', ['--sleds', '1e308']),
    'behavior_demo cycles 1e9': ('rftgls_ros.demo', ['--cycles', '1000000000']),
}


def _problem(code, err: str, out: str) -> str | None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if code != 2:
        return f'exit {code}, stdout {out[:200]!r}, stderr {err[-200:]!r}'
    if len(lines) != 1 or 'Traceback' in err:
        return f'{len(lines)} stderr lines: {err[-300:]!r}'
    if out.strip():
        return f'answered: {out[:200]!r}'
    return None


def test_every_bad_value_class_of_rftgls_is_refused(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)    # outputs, if any were written, land here: none must
    failures = {}
    for name, argv in CASES.items():
        code = rftgls(argv)
        cap = capsys.readouterr()
        if (problem := _problem(code, cap.err, cap.out)):
            failures[name] = problem
    assert not failures, '\n'.join(f'{k}: {v}' for k, v in failures.items())
    assert not list(tmp_path.iterdir())


def test_every_bad_value_class_of_the_lab_tools_is_refused(capsys, tmp_path, monkeypatch):
    import importlib
    monkeypatch.chdir(tmp_path)
    failures = {}
    for name, (module, argv) in LAB.items():
        try:
            code = importlib.import_module(module).main(argv)
        except SystemExit as exc:
            code = exc.code
        cap = capsys.readouterr()
        if (problem := _problem(code, cap.err, cap.out)):
            failures[name] = problem
    assert not failures, '\n'.join(f'{k}: {v}' for k, v in failures.items())
    assert not list(tmp_path.iterdir())


def test_the_range_of_a_value_is_named_in_the_error(capsys):
    assert rftgls(CAP + ['--phi', '1e308']) == 2
    err = capsys.readouterr().err
    assert 'tether angle phi must be in -90..90 deg' in err and '1e+308' in err


@pytest.mark.parametrize('old, new, must', [
    ('<mass value="0.040"/>', '<mass value="1e308"/>', 'mass must be in'),
    ('<mass value="0.040"/>', '<mass value="-5"/>', 'mass must be in'),
    ('scale="0.001 0.001 0.001"', 'scale="0 0 0"', 'mesh scale'),
    ('scale="0.001 0.001 0.001"', 'scale="1e300 1e300 1e300"', 'mesh scale'),
    ('<origin xyz="0 0 0" rpy="0 0 0"/>\n  </joint>',
     '<origin xyz="1e308 0 0" rpy="0 0 0"/>\n  </joint>', 'position must be in'),
    ('<joint name="winch_joint" type="fixed">',
     '<joint name="winch_joint" type="revolute"><axis xyz="0 0 0"/>', 'no direction'),
])
def test_description_values_outside_their_range_are_refused(tmp_path, capsys, old, new, must):
    """A URDF's masses, origins, mesh scales and joint axes are input too."""
    import shutil
    folder = Path(ANCHOR).parent
    shutil.copy(folder / 'ellipsoid.stl', tmp_path)
    urdf = (folder / 'ellipsoid.urdf').read_text()
    assert old in urdf
    (tmp_path / 'ellipsoid.urdf').write_text(urdf.replace(old, new))
    shutil.copy(ANCHOR, tmp_path)
    code = rftgls(['capacity', '--anchor', str(tmp_path / 'ellipsoid.yaml'), '--state',
                   'depth=-0.05', '--state', 'tilt=-30', '--json'])
    cap = capsys.readouterr()
    assert _problem(code, cap.err, cap.out) is None, (cap.err, cap.out)
    assert must in cap.err


def test_every_lab_tool_refuses_a_bag_that_is_not_a_pull_test(tmp_path, capsys):
    """A real rosbag2 of a robot (joint states and transforms, known types, no pull-test
    metadata) given to every lab tool that takes a bag: one line, exit 2. The replay refuses
    before ROS starts, so nothing can reach the live graph."""
    import importlib

    import numpy as np
    import rclpy
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / 'drive_log'
    T = ts.types
    with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection('/joint_states', 'sensor_msgs/msg/JointState', typestore=ts)
        for k in range(50):
            msg = T['sensor_msgs/msg/JointState'](
                header=T['std_msgs/msg/Header'](
                    stamp=T['builtin_interfaces/msg/Time'](sec=k, nanosec=0), frame_id=''),
                name=['leg_proximal_left'], position=np.array([0.1 * k]),
                velocity=np.array([], float), effort=np.array([], float))
            w.write(c, 10**9 * k, ts.serialize_cdr(msg, 'sensor_msgs/msg/JointState'))
    import json
    from dataclasses import asdict

    from rftgls_ros.lab.bag_layout import CameraCalibration
    camera = tmp_path / 'camera.json'
    camera.write_text(json.dumps(asdict(CameraCalibration.simple(640, 480, 600.0))))
    tools = {
        'replay': ('rftgls_ros.lab.replay', [str(bag), '--wait-subscribers', '0']),
        'evaluate': ('rftgls_ros.lab.evaluate', [str(bag), '--out-dir', str(tmp_path / 'e')]),
        'calibrate': ('rftgls_ros.lab.calibrate', [str(bag), '--out', str(tmp_path / 'c.json')]),
        'track': ('rftgls_ros.lab.aruco_tracking', ['--images', str(tmp_path), '--camera',
                                                    str(camera), '--bag-in', str(bag), '--out',
                                                    str(tmp_path / 't')]),
        'rftgls calibrate': ('rftgls_core.cli.main', ['calibrate', str(bag), '--out',
                                                      str(tmp_path / 'c.json')]),
    }
    was_ok = rclpy.ok()
    for name, (module, argv) in tools.items():
        code = importlib.import_module(module).main(argv)
        cap = capsys.readouterr()
        assert _problem(code, cap.err, cap.out) is None, (name, cap.err, cap.out)
        assert 'drive_log' in cap.err, (name, cap.err)
    assert rclpy.ok() == was_ok          # the replay never initialised ROS
    assert sorted(p.name for p in tmp_path.iterdir()) == ['camera.json', 'drive_log']
