"""safe_read, safe_write and the description sandbox, each rule checked on its own
(docs/design/safe-io.md); the campaigns over every tool are tests/lab/test_fault_*.py."""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest

from rftgls_conventions import safe_read as sr
from rftgls_conventions.safe_read import InputFileError
from rftgls_conventions.safe_write import (
    OutputError,
    atomic_write,
    open_fresh,
    output_file,
    output_folder,
    write_text,
)
from rftgls_core.cli.main import main

ANCHORS = Path(__file__).resolve().parents[2] / 'examples' / 'anchors'
SECRET = 'correct-horse-battery-staple'


def one_line_exit_2(capsys, argv: list[str]) -> str:
    code = main(argv)
    cap = capsys.readouterr()
    lines = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and not cap.out.strip(), (code, cap.err, cap.out)
    return lines[0]


# ------------------------------------------------------------------------------ reading
def test_special_files_are_refused_before_reading(tmp_path):
    fifo = tmp_path / 'pipe.stl'
    os.mkfifo(fifo)
    t0 = time.monotonic()
    with pytest.raises(InputFileError, match='is a FIFO, not a regular file'):
        sr.read_bytes(fifo, 'mesh')     # no writer: a blocking open would never return
    with pytest.raises(InputFileError, match='character device'):
        sr.read_bytes('/dev/zero', 'mesh')
    with pytest.raises(InputFileError, match='is a directory'):
        sr.read_bytes(tmp_path, 'mesh')
    assert time.monotonic() - t0 < 1.0


def test_the_size_limit_is_checked_before_reading(tmp_path):
    big = tmp_path / 'big.json'
    with open(big, 'wb') as fh:
        fh.truncate(sr.MAX_BYTES['medium'] + 1)     # sparse: nothing to read quickly
    with pytest.raises(InputFileError, match=f'{sr.MAX_BYTES["medium"] + 1} bytes'):
        sr.read_bytes(big, 'medium')
    ok = tmp_path / 'ok.json'
    ok.write_bytes(b'x' * sr.MAX_BYTES['medium'])
    assert len(sr.read_bytes(ok, 'medium')) == sr.MAX_BYTES['medium']


def test_json_nesting_is_bounded_without_recursion():
    deep = '[' * 100_000 + ']' * 100_000
    assert sr.json_depth(deep) == 100_000
    with pytest.raises(InputFileError, match='nested deeper than 64'):
        sr.parse_json(deep, 'deep.json')
    edge = '[' * sr.MAX_NESTING + ']' * sr.MAX_NESTING
    assert sr.parse_json(edge, 'edge.json') is not None
    assert sr.json_depth('{"a": "[[[[", "b": [1]}') == 2      # brackets in strings skipped


def billion_laughs(levels: int = 9) -> str:
    text = 'a0: &a0 [x, x, x, x, x, x, x, x, x]\n'
    for k in range(1, levels + 1):
        text += f'a{k}: &a{k} [' + ', '.join([f'*a{k - 1}'] * 9) + ']\n'
    return text


def test_yaml_aliases_and_nesting_are_bounded():
    with pytest.raises(InputFileError, match='expands to more than'):
        sr.parse_yaml(billion_laughs(), 'bomb.yaml')            # 81 aliases, 9**10 nodes
    with pytest.raises(InputFileError, match='refers to itself'):
        sr.parse_yaml('a: &a [1, *a]\n', 'loop.yaml')
    many = 'a: &a 1\nb: [' + ', '.join(['*a'] * (sr.MAX_ALIASES + 1)) + ']\n'
    with pytest.raises(InputFileError, match='aliases'):
        sr.parse_yaml(many, 'many.yaml')
    with pytest.raises(InputFileError, match='nested deeper'):
        sr.parse_yaml('[' * 100 + ']' * 100, 'deep.yaml')
    fine = 'r: &r [1, 2]\np: {lo: *r, hi: *r}\n'
    assert sr.parse_yaml(fine, 'fine.yaml') == {'r': [1, 2], 'p': {'lo': [1, 2], 'hi': [1, 2]}}


def test_a_parse_error_does_not_quote_the_file():
    with pytest.raises(InputFileError) as err:
        sr.parse_yaml(f'key: [{SECRET}\n', 'x.yaml')
    assert SECRET not in str(err.value) and 'line' in str(err.value)
    with pytest.raises(InputFileError) as err:
        sr.parse_json(f'{{"k": {SECRET}}}', 'x.json')
    assert SECRET not in str(err.value)


# ------------------------------------------------------------------------------ writing
def test_atomic_write_replaces_a_planted_link_and_spares_its_target(tmp_path):
    victim = tmp_path / 'victim'
    victim.write_text('precious\n')
    out = tmp_path / 'out.csv'
    out.symlink_to(victim)
    write_text(out, 'a,b\n')
    assert not out.is_symlink() and out.read_text() == 'a,b\n'
    assert victim.read_text() == 'precious\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['out.csv', 'victim']   # no temps


def test_a_folder_output_replaces_a_link_and_refuses_a_folder(tmp_path):
    victim = tmp_path / 'victim_dir'
    victim.mkdir()
    bag = tmp_path / 'bag'
    bag.symlink_to(victim, target_is_directory=True)
    with atomic_write(bag, folder=True) as tmp:
        tmp.mkdir()
        (tmp / 'data').write_text('new')
    assert bag.is_dir() and not bag.is_symlink() and not list(victim.iterdir())
    with pytest.raises(OutputError, match='already exists'):
        with atomic_write(bag, folder=True) as tmp:
            tmp.mkdir()
    with pytest.raises(OutputError, match='is a folder'):
        write_text(victim, 'x')


def test_open_fresh_never_writes_through_a_link(tmp_path):
    victim = tmp_path / 'victim'
    victim.write_text('precious\n')
    log = tmp_path / 'node.log'
    log.symlink_to(victim)
    with open_fresh(log) as fh:
        fh.write('started\n')
    assert not log.is_symlink() and log.read_text() == 'started\n'
    assert victim.read_text() == 'precious\n'


def test_what_out_means_is_checked(tmp_path):
    (tmp_path / 'folder').mkdir()
    (tmp_path / 'a_file').write_text('x')
    with pytest.raises(OutputError, match='is a folder; give a file name'):
        output_file(tmp_path / 'folder', '--out', ('.png',))
    with pytest.raises(OutputError, match='is a folder'):
        output_file(f'{tmp_path}/new/', '--out')
    with pytest.raises(OutputError, match='must end with .png'):
        output_file(tmp_path / 'plot', '--out', ('.png',))
    with pytest.raises(OutputError, match='not a folder'):
        output_file(tmp_path / 'a_file' / 'x.png', '--out', ('.png',))
    with pytest.raises(OutputError, match='exists and is not a folder'):
        output_folder(tmp_path / 'a_file', '--out-dir')
    assert output_folder(tmp_path / 'later', '--out-dir') == tmp_path / 'later'
    assert not (tmp_path / 'later').exists()          # made by the first write, not before


def test_plot_into_a_folder_is_refused_not_guessed(tmp_path, capsys):
    (tmp_path / 'DIR').mkdir()
    line = one_line_exit_2(capsys, ['plot', '--h', '0.034', '--theta-b', '5', '--theta-l1',
                                    '-40', '--theta-l2', '30', '--out', str(tmp_path / 'DIR')])
    assert 'is a folder' in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ['DIR']     # no DIR.png beside it


def test_an_unwritable_output_fails_before_the_work(tmp_path, capsys):
    """No progress bar and no computation before the error: the check comes first."""
    (tmp_path / 'a_file').write_text('x')
    t0 = time.monotonic()
    line = one_line_exit_2(capsys, ['map', 'build', '--robot', 'minirquad', '--medium',
                                    'm90_sand', '--out', str(tmp_path / 'a_file' / 'm.h5')])
    assert 'not a folder' in line and time.monotonic() - t0 < 5.0


def test_an_unreachable_dask_scheduler_fails_in_seconds(tmp_path, capsys):
    t0 = time.monotonic()
    line = one_line_exit_2(capsys, ['map', 'build', '--robot', 'minirquad', '--medium',
                                    'm90_sand', '--scheduler', 'tcp://127.0.0.1:1', '--out',
                                    str(tmp_path / 'm.h5')])
    assert 'cannot reach Dask scheduler' in line and time.monotonic() - t0 < 5.0
    assert not (tmp_path / 'm.h5').exists()


# ------------------------------------------------------------------------------ descriptions
def description_with(tmp_path: Path, urdf_text: str, name: str = 'body.urdf.xacro') -> Path:
    d = tmp_path / 'desc'
    d.mkdir(exist_ok=True)
    shutil.copy(ANCHORS / 'ellipsoid.stl', d / 'ellipsoid.stl')
    (d / name).write_text(urdf_text)
    yml = d / 'body.yaml'
    yml.write_text((ANCHORS / 'ellipsoid.yaml').read_text().replace('urdf: ellipsoid.urdf',
                                                                    f'urdf: {name}'))
    return yml


def xacro_with(line: str) -> str:
    return (ANCHORS / 'ellipsoid.urdf').read_text().replace(
        '<robot name="ellipsoid_anchor">',
        '<robot name="ellipsoid_anchor" xmlns:xacro="http://www.ros.org/wiki/xacro">' + line)


STATE = ['--state', 'depth=-0.05', '--state', 'tilt=-30', '--json']


def test_xacro_reads_no_environment_and_does_not_print_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv('RFTGLS_TEST_SECRET', SECRET)
    yml = description_with(tmp_path, xacro_with('<link name="x$(env RFTGLS_TEST_SECRET)"/>'))
    line = one_line_exit_2(capsys, ['capacity', '--anchor', str(yml), *STATE])
    assert 'reads no environment' in line and SECRET not in line
    yml = description_with(tmp_path, xacro_with(
        '<link name="x$(eval optenv(\'RFTGLS_TEST_SECRET\'))"/>'))
    line = one_line_exit_2(capsys, ['capacity', '--anchor', str(yml), *STATE])
    assert SECRET not in line


def test_xacro_reads_only_inside_the_allow_list(tmp_path, capsys):
    outside = tmp_path / 'elsewhere.yaml'
    outside.write_text(f'secret: {SECRET}\n')
    yml = description_with(tmp_path, xacro_with(
        f'<link name="y${{len(xacro.load_yaml(\'{outside}\'))}}"/>'))
    line = one_line_exit_2(capsys, ['capacity', '--anchor', str(yml), *STATE])
    assert 'outside the description' in line and SECRET not in line
    yml = description_with(tmp_path, xacro_with('<xacro:include filename="../elsewhere.yaml"/>'))
    assert 'outside the description' in one_line_exit_2(
        capsys, ['capacity', '--anchor', str(yml), *STATE])
    yml = description_with(tmp_path, xacro_with('<xacro:include filename="*.xacro"/>'))
    assert 'include pattern' in one_line_exit_2(capsys, ['capacity', '--anchor', str(yml),
                                                         *STATE])
    mesh_outside = (ANCHORS / 'ellipsoid.urdf').read_text().replace(
        'filename="ellipsoid.stl"', f'filename="{ANCHORS / "ellipsoid.stl"}"')
    yml = description_with(tmp_path, mesh_outside, 'body.urdf')
    assert 'outside the description' in one_line_exit_2(
        capsys, ['capacity', '--anchor', str(yml), *STATE])


def test_an_allowed_xacro_still_expands_and_the_sandbox_is_removed(tmp_path, capsys):
    import xacro
    from xacro import substitution_args
    before = (xacro.abs_filename_spec, substitution_args._eval_env)
    inner = tmp_path / 'desc' / 'values.yaml'
    inner.parent.mkdir()
    inner.write_text('mass: 0.040\n')
    yml = description_with(tmp_path, xacro_with(
        '<xacro:property name="v" value="${xacro.load_yaml(\'values.yaml\')}"/>').replace(
        '<mass value="0.040"/>', '<mass value="${v[\'mass\']}"/>'))
    assert main(['capacity', '--anchor', str(yml), *STATE]) == 0
    assert '"status": "ok"' in capsys.readouterr().out
    assert (xacro.abs_filename_spec, substitution_args._eval_env) == before


@pytest.mark.parametrize('doc, field', [
    ('state: oops', '`state:`'),
    ('state: [{name: depth, unit: m, physical: [null, 0]}]', '`physical:`'),
    ('surface_points: [[0, 0, x]]', '`surface_points:`'),
    ('char_length_m: [1]', '`char_length_m:`'),
])
def test_a_description_of_the_wrong_shape_is_one_line(tmp_path, capsys, doc, field):
    text = (ANCHORS / 'ellipsoid.yaml').read_text()
    key = doc.split(':')[0]
    lines = [ln for ln in text.splitlines() if not ln.startswith(key)]
    if key == 'state':
        lines = [ln for ln in lines if not ln.startswith('  - {name')]
    (tmp_path / 'bad.yaml').write_text('\n'.join(lines) + f'\n{doc}\n')
    for f in ('ellipsoid.urdf', 'ellipsoid.stl'):
        shutil.copy(ANCHORS / f, tmp_path / f)
    assert field in one_line_exit_2(capsys, ['capacity', '--anchor', str(tmp_path / 'bad.yaml'),
                                             *STATE])


def test_hostile_documents_are_input_errors_not_internal_ones(tmp_path, capsys):
    (tmp_path / 'deep.json').write_text('[' * 100_000 + ']' * 100_000)
    assert 'nested deeper' in one_line_exit_2(capsys, [
        'capacity', '--h', '0.034', '--theta-b', '5', '--theta-l1', '-40', '--theta-l2', '30',
        '--medium', str(tmp_path / 'deep.json')])
    (tmp_path / 'bomb.yaml').write_text(billion_laughs() + 'urdf: x.urdf\nstate: *a9\n')
    assert 'expands to more than' in one_line_exit_2(capsys, [
        'capacity', '--anchor', str(tmp_path / 'bomb.yaml')])


def test_a_map_declaring_a_huge_dataset_is_refused_before_reading(tmp_path, capsys):
    """HDF5 lets a small file declare a dataset of any shape (never written: fill values);
    reading it would allocate what it declares. 2e9 float64 = 16 GB in a file of kilobytes."""
    import h5py

    from rftgls_core.maps import SHIPPED, maps_dir
    bad = tmp_path / 'huge_axis.h5'
    shutil.copy(maps_dir() / SHIPPED['minirquad'], bad)
    with h5py.File(bad, 'a') as f:
        del f['axes/h']
        f['axes'].create_dataset('h', shape=(2 * 10**9,), dtype='f8', chunks=(4096,),
                                 compression='gzip')
    assert bad.stat().st_size < 10**6
    assert 'would take more than' in one_line_exit_2(capsys, ['map', 'info', str(bad)])
