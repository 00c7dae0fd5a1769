"""The CLI contract over a corpus of bad input: every bad invocation
of `rftgls` (bags, media, meshes, maps, penetration CSVs, options, states) ends with exit 2
and exactly ONE line on stderr, never a traceback and never a value.

The files are generated here, in tmp_path. The corpus runs in-process through
rftgls_core.cli.main.main(argv) (fast); a few cases also go through the real `rftgls`
executable in a subprocess.
"""
from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

pytest.importorskip('rosbags')

from rftgls_core.cli.main import main  # noqa: E402
from rftgls_core.geometry.shapes import c_leg  # noqa: E402
from rftgls_core.geometry.stl import write_stl  # noqa: E402
from rftgls_core.maps import SHIPPED, maps_dir  # noqa: E402
from rftgls_core.maps.hdf5 import HASH_ATTR  # noqa: E402

SAMPLES = Path(__file__).resolve().parents[2] / 'src/rftgls_ros/rftgls_ros/lab/samples'
GOOD_BAG = SAMPLES / 'backward_L1-020_L2+020'
DH = ['--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30']


# ------------------------------------------------------------------------------- bad files
def _bag_with(path: Path, connections: list[tuple[str, str, bytes]]) -> Path:
    """A real rosbag2 (mcap) with the given (topic, type, payload) messages, types unchecked."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=8, storage_plugin=StoragePlugin.MCAP) as w:
        for i, (topic, msgtype, payload) in enumerate(connections):
            if msgtype in ts.types:
                c = w.add_connection(topic, msgtype, typestore=ts)
            else:
                c = w.add_connection(topic, msgtype, msgdef='int32 x', rihs01='RIHS01_' + '0' * 64)
            w.write(c, 1_000 + i, payload)
    return path


def _string_msg(text: str) -> bytes:
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    return ts.serialize_cdr(ts.types['std_msgs/msg/String'](data=text), 'std_msgs/msg/String')


def _float_msg(x: float) -> bytes:
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    return ts.serialize_cdr(ts.types['std_msgs/msg/Float64'](data=x), 'std_msgs/msg/Float64')


def make_bags(d: Path) -> dict[str, Path]:
    mcap = GOOD_BAG / f'{GOOD_BAG.name}.mcap'
    out = {}

    def copy(name: str) -> Path:
        p = d / name
        shutil.copytree(GOOD_BAG, p)
        return p

    p = copy('truncated')
    (p / mcap.name).write_bytes(mcap.read_bytes()[:3000])
    out['truncated'] = p
    p = copy('truncated_late')
    (p / mcap.name).write_bytes(mcap.read_bytes()[:-200])
    out['truncated_late'] = p
    p = copy('garbage')
    (p / mcap.name).write_bytes(np.random.default_rng(1).bytes(5000))
    out['garbage'] = p
    p = copy('zero_bytes')
    (p / mcap.name).write_bytes(b'')
    out['zero_bytes'] = p
    p = copy('missing_mcap')
    (p / mcap.name).unlink()
    out['missing_mcap'] = p
    p = copy('garbage_yaml')
    (p / 'metadata.yaml').write_text('rosbag2_bagfile_information: [::: not yaml\n')
    out['garbage_yaml'] = p
    p = copy('empty_yaml')
    (p / 'metadata.yaml').write_text('')
    out['empty_yaml'] = p
    out['plain_file'] = d / 'plain.txt'
    out['plain_file'].write_text('not a bag\n')
    out['plain_mcap'] = d / 'plain.mcap'
    out['plain_mcap'].write_text('not an mcap either\n')
    out['empty_dir'] = d / 'empty_dir'
    out['empty_dir'].mkdir()
    out['nonexistent'] = d / 'no_such_bag'
    out['wrong_type'] = _bag_with(d / 'wrong_type', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg('{}')),
        ('/winch/tension', 'std_msgs/msg/Float64', _float_msg(3.0))])
    out['hostile_type'] = _bag_with(d / 'hostile_type', [
        ('/winch/tension', 'os/msg/System', b'\x00\x01\x00\x00\x05\x00\x00\x00')])
    out['no_metadata'] = _bag_with(d / 'no_metadata', [
        ('/winch/phi', 'std_msgs/msg/Float64', _float_msg(0.0))])
    out['metadata_not_json'] = _bag_with(d / 'metadata_not_json', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg('{not json'))])
    out['metadata_wrong_schema'] = _bag_with(d / 'metadata_wrong_schema', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg('{"schema": "other"}'))])
    out['metadata_list'] = _bag_with(d / 'metadata_list', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg('[1, 2, 3]'))])
    meta = json.loads(_read_meta_json(GOOD_BAG))
    out['no_tension'] = _bag_with(d / 'no_tension', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg(json.dumps(meta)))])
    broken = dict(meta, initial_state={'h_m': None})
    out['metadata_null_state'] = _bag_with(d / 'metadata_null_state', [
        ('/lab/metadata', 'std_msgs/msg/String', _string_msg(json.dumps(broken)))])
    return out


def _read_meta_json(bag: Path) -> str:
    from rftgls_ros.lab.bag_layout import read_metadata
    return read_metadata(bag).to_json()


def make_csvs(d: Path) -> dict[str, Path]:
    texts = {
        'one_column': 'depth_m\n0.01\n0.02\n',
        'empty': '',
        'header_only': 'depth_m,force_N\n',
        'not_numbers': 'depth_m,force_N\n0.01,abc\n0.02,1.0\n',
        'nan_depth': 'depth_m,force_N\nnan,0.5\n0.02,1.0\n',
        'negative_depth': 'depth_m,force_N\n-0.01,0.5\n0.02,1.0\n',
        'inf_force': 'depth_m,force_N\n0.01,inf\n0.02,1.0\n',
        'ragged': 'depth_m,force_N\n0.01,0.5,7\n0.02,1.0\n',
        'wrong_header': 'depth,force\n0.01,0.5\n0.02,1.0\n',
        'no_header': '0.01,0.5\n0.02,1.0\n',
        'one_sample': 'depth_m,force_N\n0.01,0.5\n',
        'test_with_one_sample': 'depth_m,force_N,test\n0.01,0.5,a\n0.02,1.0,a\n0.01,0.4,b\n',
        'semicolons': 'depth_m;force_N\n0.01;0.5\n0.02;1.0\n',
    }
    out = {k: d / f'{k}.csv' for k in texts}
    for k, t in texts.items():
        out[k].write_text(t)
    out['binary'] = d / 'binary.csv'
    out['binary'].write_bytes(b'\xff\xfe\x00\x81' * 50)
    out['good'] = d / 'good.csv'
    out['good'].write_text('depth_m,force_N\n0.01,0.5\n0.02,1.0\n0.03,1.5\n')
    return out


def make_media(d: Path) -> dict[str, Path]:
    base = {'name': 'm', 'xi_n': 3.8e5, 'mu_surf': 0.4, 'zeta': 3.3e5}
    variants = {
        'xi_null': dict(base, xi_n=None), 'xi_string': dict(base, xi_n='3.8e5'),
        'xi_bool': dict(base, xi_n=True), 'xi_zero': dict(base, xi_n=0),
        'xi_negative': dict(base, xi_n=-1.0), 'xi_list': dict(base, xi_n=[3.8e5]),
        'xi_object': dict(base, xi_n={'value': 3.8e5}), 'mu_null': dict(base, mu_surf=None),
        'mu_string': dict(base, mu_surf='rough'), 'mu_negative': dict(base, mu_surf=-0.1),
        'zeta_null': dict(base, zeta=None), 'zeta_string': dict(base, zeta='big'),
        'name_number': dict(base, name=5), 'name_null': dict(base, name=None),
        'coeffs_number': dict(base, li_coefficients=3), 'note_list': dict(base, note=['x']),
        'missing_xi': {k: v for k, v in base.items() if k != 'xi_n'},
    }
    out = {}
    for k, v in variants.items():
        out[k] = d / f'{k}.json'
        out[k].write_text(json.dumps(v))
    raw = {'list': '[1, 2]', 'string': '"glass_beads"', 'empty': '', 'not_json': '{xi_n: 1',
           'nan_mu': '{"name": "m", "xi_n": 3.8e5, "mu_surf": NaN, "zeta": 3.3e5}',
           'inf_xi': '{"name": "m", "xi_n": Infinity, "mu_surf": 0.4, "zeta": 3.3e5}',
           'huge_xi': '{"name": "m", "xi_n": 1e999, "mu_surf": 0.4, "zeta": 3.3e5}'}
    for k, t in raw.items():
        out[k] = d / f'{k}.json'
        out[k].write_text(t)
    out['binary'] = d / 'binary.json'
    out['binary'].write_bytes(b'\xff\xfe\x00\x81' * 20)
    out['directory'] = d / 'a_dir.json'
    out['directory'].mkdir()
    return out


def make_meshes(d: Path) -> dict[str, Path]:
    out = {}
    leg = c_leg(arc_diameter=0.09, thickness=0.005, width=0.01, n_arc=12)
    tri = leg.vertices[leg.faces] * 1e3                               # mm

    def binary(name: str, triangles: np.ndarray, count: int | None = None) -> Path:
        p = d / f'{name}.stl'
        n = len(triangles) if count is None else count
        body = b''.join(struct.pack('<12fH', 0, 0, 0, *t.reshape(-1), 0) for t in triangles)
        p.write_bytes(b'\0' * 80 + struct.pack('<I', n) + body)
        return p

    far = np.array([[[1e8, 1e8, 1e8], [1e8 + 5, 1e8, 1e8], [1e8, 1e8 + 5, 1e8]]])
    out['stray_triangle'] = binary('stray', np.concatenate([tri, far]))
    out['truncated'] = binary('truncated', tri, count=len(tri) + 7)
    out['zero_triangles'] = binary('zero', tri[:0])
    out['all_degenerate'] = binary('degenerate', np.repeat(tri[:, :1], 3, axis=1))
    nan = tri.copy()
    nan[3, 1, 2] = np.nan
    out['nan_vertex'] = binary('nan', nan)
    out['huge_count'] = binary('huge', tri[:2], count=3_000_000)
    texts = {'empty': '', 'ascii_no_endsolid': 'solid x\nfacet normal 0 0 1\nouter loop\n'
             'vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n',
             'ascii_bad_vertex': 'solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n'
             'vertex 1 zero 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid x\n',
             'ascii_two_vertices': 'solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n'
             'vertex 1 0 0\nendloop\nendfacet\nendsolid x\n',
             'text': 'hello, this is not a mesh\n', 'short_binary': 'x' * 40}
    for k, t in texts.items():
        out[k] = d / f'{k}.stl'
        out[k].write_text(t)
    out['directory'] = d / 'dir.stl'
    out['directory'].mkdir()
    out['nonexistent'] = d / 'nope.stl'
    out['good'] = d / 'good.stl'
    write_stl(out['good'], leg, units='mm')
    return out


def make_maps(d: Path) -> dict[str, Path]:
    shipped = maps_dir() / SHIPPED['minirquad']
    out = {}

    def copy(name: str) -> Path:
        p = d / f'{name}.h5'
        shutil.copy(shipped, p)
        return p

    def edit(name: str, fn) -> None:
        out[name] = copy(name)
        with h5py.File(out[name], 'a') as f:
            fn(f)

    def scale(f):
        f['capacity_N'][...] = f['capacity_N'][()] * 2.0

    def one_value(f):
        c = f['capacity_N'][()]
        i = np.argwhere(np.isfinite(c))[100]
        c[tuple(i)] += 0.01
        f['capacity_N'][...] = c

    def swap(f):
        labels = list(f['axes/pull'].asstr()[()])
        del f['axes/pull']
        f['axes'].create_dataset('pull', data=np.array(labels[::-1], dtype=object),
                                 dtype=h5py.string_dtype())

    def flip(f):
        a = f['axes/h'][()].view(np.uint64).copy()
        a[2] ^= np.uint64(1 << 3)
        f['axes/h'][...] = a.view(np.float64)

    def twist(f):
        t = f['slip_twist'][()]
        t[0, 0, 0, 0, 0, 0] = -t[0, 0, 0, 0, 0, 0]
        f['slip_twist'][...] = t

    def robot(f):
        f.attrs['robot'] = 'prototype'

    def medium(f):
        f.attrs['medium'] = 'glass_beads'

    def drop(f):
        del f['reason']

    def schema(f):
        f.attrs['schema'] = 'something.else'

    def version(f):
        f.attrs['schema_version'] = 99

    def bad_hash(f):
        f.attrs[HASH_ATTR] = '0' * 64

    for name, fn in (('doubled', scale), ('one_value', one_value), ('pulls_swapped', swap),
                     ('axis_bit', flip), ('twist_flipped', twist), ('robot_relabelled', robot),
                     ('medium_relabelled', medium), ('no_reason', drop),
                     ('wrong_schema', schema), ('newer_version', version),
                     ('wrong_hash', bad_hash)):
        edit(name, fn)
    out['truncated'] = d / 'truncated.h5'
    out['truncated'].write_bytes(shipped.read_bytes()[:50_000])
    out['garbage'] = d / 'garbage.h5'
    out['garbage'].write_bytes(np.random.default_rng(2).bytes(4000))
    out['empty'] = d / 'empty.h5'
    out['empty'].write_bytes(b'')
    out['text'] = d / 'text.h5'
    out['text'].write_text('hello\n')
    out['directory'] = d / 'dir.h5'
    out['directory'].mkdir()
    out['nonexistent'] = d / 'nope.h5'
    out['prototype'] = maps_dir() / SHIPPED['prototype']
    return out


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp('bad_inputs')
    out = {}
    for kind, make in (('bag', make_bags), ('csv', make_csvs), ('medium', make_media),
                       ('mesh', make_meshes), ('map', make_maps)):
        sub = d / kind
        sub.mkdir()
        out.update({f'{kind}:{k}': str(v) for k, v in make(sub).items()})
    out['out'] = str(d / 'out.json')
    return out


# ------------------------------------------------------------------------------- the corpus
TAMPERED = ('doubled', 'one_value', 'pulls_swapped', 'axis_bit', 'twist_flipped',
            'robot_relabelled', 'medium_relabelled', 'wrong_hash')


def corpus(f: dict[str, str], expect: dict[str, str]) -> list[tuple[str, list[str]]]:
    """(name, argv) of every bad invocation; `expect` gets, per name, a text the error line
    must hold (the file's name, or the reason), so a case cannot pass by failing elsewhere."""
    cases: list[tuple[str, list[str]]] = []
    wrench = ['wrench', '--mesh', f['mesh:good'], '--twist', '1', '0', '0', '0', '0', '0']
    # bags
    for k in ('truncated', 'truncated_late', 'garbage', 'zero_bytes', 'missing_mcap',
              'garbage_yaml', 'empty_yaml', 'plain_file', 'plain_mcap', 'empty_dir',
              'nonexistent', 'wrong_type', 'hostile_type', 'no_metadata', 'metadata_not_json',
              'metadata_wrong_schema', 'metadata_list', 'no_tension', 'metadata_null_state'):
        cases.append((f'bag {k}', ['calibrate', f[f'bag:{k}'], '--out', f['out']]))
        expect[f'bag {k}'] = Path(f[f'bag:{k}']).name
    cases.append(('bag good then bad', ['calibrate', str(GOOD_BAG), f['bag:garbage'],
                                        '--out', f['out']]))
    cases.append(('bag twice', ['calibrate', str(GOOD_BAG), str(GOOD_BAG), '--out', f['out']]))
    # penetration CSVs
    for k in ('one_column', 'empty', 'header_only', 'not_numbers', 'nan_depth',
              'negative_depth', 'inf_force', 'ragged', 'wrong_header', 'no_header',
              'one_sample', 'test_with_one_sample', 'semicolons', 'binary'):
        cases.append((f'csv {k}', ['calibrate', '--penetration', f[f'csv:{k}'],
                                   '--plate-area', '1e-3', '--out', f['out']]))
        expect[f'csv {k}'] = Path(f[f'csv:{k}']).name
    good = f['csv:good']
    cases += [
        ('csv missing file', ['calibrate', '--penetration', f['csv:good'] + '.nope',
                              '--plate-area', '1e-3']),
        ('csv no plate area', ['calibrate', '--penetration', good]),
        ('csv plate area 0', ['calibrate', '--penetration', good, '--plate-area', '0']),
        ('csv plate area negative', ['calibrate', '--penetration', good, '--plate-area',
                                     '-1e-3']),
        ('csv plate area nan', ['calibrate', '--penetration', good, '--plate-area', 'nan']),
        ('csv two areas one file', ['calibrate', '--penetration', good, '--plate-area', '1e-3',
                                    '--plate-area', '2e-3']),
        ('csv area without file', [' calibrate'.strip(), str(GOOD_BAG), '--plate-area', '1e-3']),
        ('csv repeated file', ['calibrate', '--penetration', good, '--penetration', good,
                               '--plate-area', '1e-3']),
        ('calibrate nothing', ['calibrate', '--out', f['out']]),
        ('calibrate sigma 0', ['calibrate', '--penetration', good, '--plate-area', '1e-3',
                               '--sigma-penetration', '0']),
        ('calibrate bad method', ['calibrate', str(GOOD_BAG), '--method', 'guess']),
    ]
    # media (capacity and wrench read them before computing anything)
    for k in ('xi_null', 'xi_string', 'xi_bool', 'xi_zero', 'xi_negative', 'xi_list',
              'xi_object', 'mu_null', 'mu_string', 'mu_negative', 'zeta_null', 'zeta_string',
              'name_number', 'name_null', 'coeffs_number', 'note_list', 'missing_xi', 'list',
              'string', 'empty', 'not_json', 'nan_mu', 'inf_xi', 'huge_xi', 'binary',
              'directory'):
        cases.append((f'medium {k}', ['capacity', *DH, '--medium', f[f'medium:{k}']]))
        expect[f'medium {k}'] = Path(f[f'medium:{k}']).name
    cases += [
        ('medium null via wrench', wrench + ['--medium', f['medium:xi_null']]),
        ('medium unknown preset', ['capacity', *DH, '--medium', 'quicksand']),
        ('medium missing file', ['capacity', *DH, '--medium', f['medium:list'] + '.gone.json']),
        ('medium and parameters', ['capacity', *DH, '--medium', 'm90_sand', '--xi-n', '4e5']),
        ('medium mu nan', ['capacity', *DH, '--xi-n', '4e5', '--mu-surf', 'nan']),
        ('medium mu negative', ['capacity', *DH, '--xi-n', '4e5', '--mu-surf', '-1e-1']),
        ('medium xi negative', ['capacity', *DH, '--xi-n', '-4e5']),
    ]
    # meshes
    for k in ('stray_triangle', 'truncated', 'zero_triangles', 'all_degenerate', 'nan_vertex',
              'huge_count', 'empty', 'ascii_no_endsolid', 'ascii_bad_vertex',
              'ascii_two_vertices', 'text', 'short_binary', 'directory', 'nonexistent'):
        cases.append((f'mesh {k}', ['wrench', '--mesh', f[f'mesh:{k}'],
                                    '--twist', '1', '0', '0', '0', '0', '0']))
        expect[f'mesh {k}'] = 'stray' if k == 'stray_triangle' else Path(f[f'mesh:{k}']).name
    w0 = ['wrench', '--mesh', f['mesh:good'], '--twist']
    cases += [
        ('twist zero', w0 + ['0', '0', '0', '0', '0', '0']),
        ('twist 1e-200', w0 + ['1e-200', '0', '0', '0', '0', '0']),
        ('twist -1e-200 mixed', w0 + ['-1e-200', '0', '0', '0', '1e-201', '0']),
        ('twist nan', w0 + ['nan', '0', '0', '0', '0', '0']),
        ('twist inf', w0 + ['inf', '0', '0', '0', '0', '0']),
        ('twist five values', w0 + ['1', '0', '0', '0', '0']),
        ('twist word', w0 + ['fast', '0', '0', '0', '0', '0']),
        ('mesh units inch', wrench + ['--units', 'inch']),
        ('mesh rpy nan', wrench + ['--rpy', '0', 'nan', '0']),
        ('mesh position inf', wrench + ['--position', '0', '0', '-inf']),
    ]
    # maps
    for k in ('doubled', 'one_value', 'pulls_swapped', 'axis_bit', 'twist_flipped',
              'robot_relabelled', 'medium_relabelled', 'no_reason', 'wrong_schema',
              'newer_version', 'wrong_hash', 'truncated', 'garbage', 'empty', 'text',
              'directory', 'nonexistent'):
        cases.append((f'map {k}', ['capacity', *DH, '--method', 'map', '--map', f[f'map:{k}']]))
        expect[f'map {k}'] = ('content hash' if k in TAMPERED else Path(f[f'map:{k}']).name)
    for k in ('doubled', 'pulls_swapped', 'axis_bit', 'garbage', 'nonexistent'):
        cases.append((f'map info {k}', ['map', 'info', f[f'map:{k}']]))
        cases.append((f'map accuracy {k}', ['map', 'accuracy', f[f'map:{k}'], '--quiet']))
        expect[f'map info {k}'] = expect[f'map accuracy {k}'] = Path(f[f'map:{k}']).name
    cases += [
        ('map of another robot', ['capacity', *DH, '--method', 'map', '--map', f['map:prototype']]),
        ('map of another robot, named', ['capacity', *DH, '--method', 'map', '--map',
                                         SHIPPED['prototype']]),
        ('map of another medium', ['capacity', *DH, '--method', 'map', '--medium', 'glass_beads']),
        ('map with medium params', ['capacity', *DH, '--method', 'map', '--xi-n', '4e5']),
        ('map without method map', ['capacity', *DH, '--map', SHIPPED['minirquad']]),
        ('simulate map of another robot', ['simulate', 'pull', *DH, '--method', 'map', '--map',
                                           f['map:prototype'], '--out', f['out']]),
        ('map build n-twists 2', ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                                  '--n-twists', '2', '--out', f['out'] + '.h5']),
        ('map build out txt', ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                               '--out', f['out'] + '.txt']),
        ('map build bad range', ['map', 'build', '--robot', 'minirquad', '--medium', 'm90_sand',
                                 '--h=5:0:30', '--out', f['out'] + '.h5']),
        ('map accuracy samples 0', ['map', 'accuracy', SHIPPED['minirquad'], '--samples', '0']),
    ]
    # states outside the robot's physical range, and other options
    cap = ['capacity', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30']
    cases += [
        ('h -10 m', cap + ['--h', '-10']),
        ('h -1e1 scientific', cap + ['--h', '-1e1']),
        ('h 1e3 m', cap + ['--h', '1e3']),
        ('h 34 (mm for m)', cap + ['--h', '34']),
        ('h nan', cap + ['--h', 'nan']),
        ('h inf', cap + ['--h', 'inf']),
        ('h missing value', cap + ['--h']),
        ('h missing', cap),
        ('theta-b 100 deg', ['capacity', '--h', '0.034', '--theta-b', '100', '--theta-l1', '-40',
                             '--theta-l2', '30']),
        ('theta-l1 270 deg', ['capacity', '--h', '0.034', '--theta-b', '5', '--theta-l1', '270',
                              '--theta-l2', '30']),
        ('theta-l2 -1e3 deg', ['capacity', '--h', '0.034', '--theta-b', '5', '--theta-l1', '-40',
                               '--theta-l2', '-1e3']),
        ('prototype h -10', ['capacity', '--robot', 'prototype', '--h', '-10', '--theta-b', '0',
                             '--theta-l1', '0', '--theta-l2', '0']),
        ('phi nan', ['capacity', *DH, '--phi', 'nan']),
        ('pull sideways', ['capacity', *DH, '--pull', 'sideways']),
        ('robot unknown', ['capacity', *DH, '--robot', 'hexapod']),
        ('method unknown', ['capacity', *DH, '--method', 'magic']),
        ('twists 0', ['capacity', *DH, '--twists', '0']),
        ('twists 7', ['capacity', *DH, '--twists', '7']),
        ('twists 1e9', ['capacity', *DH, '--twists', '1000000000']),
        ('twists word', ['capacity', *DH, '--twists', 'many']),
        ('twists float', ['capacity', *DH, '--twists', '1e3']),
        ('unknown option', ['capacity', *DH, '--bogus']),
        ('repeated single option', ['capacity', *DH, '--h', '0.02']),
        ('simulate step 0', ['simulate', 'pull', *DH, '--step', '0', '--out', f['out']]),
        ('simulate too many steps', ['simulate', 'pull', *DH, '--step', '1e-9', '--out',
                                     f['out']]),
        ('simulate h -10', ['simulate', 'pull', '--h', '-10', '--theta-b', '0', '--theta-l1', '0',
                            '--theta-l2', '0', '--out', f['out']]),
        ('no command', []),
        ('unknown command', ['teleport']),
    ]
    return cases


def _check(argv: list[str], capsys, expect: str = '') -> str | None:
    """None when argv ends as the contract says; else what went wrong."""
    code = main(argv)
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.strip()]
    if code != 2:
        return f'exit {code}, stderr {captured.err[-300:]!r}'
    if len(lines) != 1 or 'Traceback' in captured.err:
        return f'{len(lines)} stderr lines: {captured.err[-400:]!r}'
    if captured.out.strip():
        return f'printed output: {captured.out[:200]!r}'
    if expect not in lines[0]:
        return f'error line lacks {expect!r}: {lines[0]!r}'
    return None


def test_corpus_of_bad_invocations_exits_2_with_one_line(files, capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)   # resolving shipped names must not depend on the cwd
    expect: dict[str, str] = {}
    cases = corpus(files, expect)
    assert len(cases) >= 100, len(cases)
    assert len({name for name, _ in cases}) == len(cases)
    failures = {}
    for name, argv in cases:
        problem = _check(argv, capsys, expect.get(name, ''))
        if problem:
            failures[name] = problem
    assert not failures, '\n'.join(f'{k}: {v}' for k, v in failures.items())


def test_negative_scientific_values_are_values(capsys):
    """`--h -1e-3` is a height, not an option (argparse's default would refuse it)."""
    code = main(['capacity', '--h', '-1e-3', '--theta-b', '5', '--theta-l1', '-40',
                 '--theta-l2', '30', '--method', 'map', '--json'])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    # -1 mm is a physical height but outside the shipped map's grid: no value.
    assert out['status'] == 'out_of_range' and out['capacity_N'] is None


def test_repeated_penetration_files_are_separate_tests(files, tmp_path, capsys):
    """`--penetration A --penetration B` uses both: before, only B counted."""
    a, b = tmp_path / 'a.csv', tmp_path / 'b.csv'
    area = 1.5e-3
    # F = 0.875 xi A depth with xi = 3e5 (A) and 5e5 (B): the fit lands between them.
    depths = np.array([0.01, 0.02, 0.03])
    for path, xi in ((a, 3e5), (b, 5e5)):
        path.write_text('depth_m,force_N\n' + ''.join(
            f'{d},{0.875 * xi * area * d}\n' for d in depths))
    outs = []
    for args in (['--penetration', str(a)], ['--penetration', str(b)],
                 ['--penetration', str(a), '--penetration', str(b)]):
        out = tmp_path / f'm{len(outs)}.json'
        assert main(['calibrate', *args, '--plate-area', str(area), '--out', str(out)]) == 0
        outs.append(json.loads(out.read_text()))
    capsys.readouterr()
    xi_a, xi_b, xi_ab = (o['xi_n'] for o in outs)
    assert xi_a == pytest.approx(3e5, rel=1e-4) and xi_b == pytest.approx(5e5, rel=1e-4)
    assert xi_a * 1.05 < xi_ab < xi_b / 1.05       # both tests counted, not only the last
    cal = outs[2]['calibration']
    assert cal['n_penetration_tests'] == 2 and cal['n_penetration_samples'] == 6
    assert cal['sources'] == [str(a), str(b)]


@pytest.mark.parametrize('argv', [
    lambda f: ['calibrate', f['bag:truncated'], '--out', f['out']],
    lambda f: ['capacity', *DH, '--method', 'map', '--map', f['map:one_value']],
    lambda f: ['capacity', *DH, '--medium', f['medium:xi_null']],
    lambda f: ['capacity', '--h', '-10', '--theta-b', '0', '--theta-l1', '0', '--theta-l2', '0'],
    lambda f: ['wrench', '--mesh', f['mesh:stray_triangle'], '--twist', '1', '0', '0', '0', '0',
               '0'],
    lambda f: ['capacity', *DH, '--twists', '1e3'],
], ids=['bag', 'map', 'medium', 'state', 'mesh', 'argparse'])
def test_real_executable_one_line_exit_2(files, argv):
    exe = shutil.which('rftgls') or str(Path(sys.executable).parent / 'rftgls')
    env = dict(os.environ, PYTHONWARNINGS='default')
    out = subprocess.run([exe, *argv(files)], capture_output=True, text=True, timeout=120,
                         env=env)
    lines = [ln for ln in out.stderr.splitlines() if ln.strip()]
    assert out.returncode == 2 and len(lines) == 1, out.stderr
    assert 'Traceback' not in out.stderr and not out.stdout.strip()
