"""Map integrity: content hash, shipped hashes, the one resolver.

A tampered map must be refused, not answered from: capacities doubled, the pull labels
swapped, one flipped bit in an axis, one changed value; a shipped map must match the hash
recorded in the package even when the attacker re-hashes the file.
"""
import shutil
import warnings

import h5py
import numpy as np
import pytest
from test_maps import state, synthetic

from rftgls_core.cli.main import main
from rftgls_core.maps import (
    SHIPPED,
    SHIPPED_SHA256,
    CapacityMap,
    MapFileError,
    MapIntegrityWarning,
    content_sha256,
    load_map,
    maps_dir,
    resolve_map,
    save_map,
)
from rftgls_core.maps.hdf5 import HASH_ATTR, STATUS_NAMES
from rftgls_core.types import Status


@pytest.fixture
def saved(tmp_path):
    return save_map(tmp_path / 'm.h5', synthetic())


def _rehash(path):
    """What an attacker who knows the scheme would do: recompute the stored hash."""
    from rftgls_core.maps.hdf5 import _read
    with h5py.File(path, 'a') as f:
        del f.attrs[HASH_ATTR]
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', MapIntegrityWarning)
            d = _read(f, None)
        f.attrs[HASH_ATTR] = content_sha256(
            d.grid, d.capacity_N, d.slip_twist_scaled, d.slip_twist, d.status, STATUS_NAMES,
            d.reason, list(d.reason_names), d.attrs, d.support_margin, d.support_margin_grad)


def test_saved_map_carries_its_hash_and_verifies(saved):
    with h5py.File(saved) as f:
        stored = f.attrs[HASH_ATTR]
    assert isinstance(stored, str) and len(stored) == 64
    with warnings.catch_warnings():
        warnings.simplefilter('error')      # a hashed map loads without any warning
        data = load_map(saved)
    assert data.integrity == 'verified'


def _double_capacity(f):
    f['capacity_N'][...] = f['capacity_N'][()] * 2.0


def _swap_pulls(f):
    labels = list(f['axes/pull'].asstr()[()])
    del f['axes/pull']
    f['axes'].create_dataset('pull', data=np.array(labels[::-1], dtype=object),
                             dtype=h5py.string_dtype())


def _flip_axis_bit(f):
    a = f['axes/theta_l2'][()]
    bits = a.view(np.uint64).copy()
    bits[1] ^= np.uint64(1)            # lowest mantissa bit: still finite and increasing
    f['axes/theta_l2'][...] = bits.view(np.float64)


def _one_value(f):
    c = f['capacity_N'][()]
    c[1, 1, 1, 0, 1, 2] *= 1.01
    f['capacity_N'][...] = c


def _status_flip(f):
    s = f['status'][()]
    s[0, 0, 0, 0, 0, 0] = list(f['status'].attrs['status_names']).index('unsupported')
    f['status'][...] = s


@pytest.mark.parametrize('tamper', [_double_capacity, _swap_pulls, _flip_axis_bit, _one_value,
                                    _status_flip])
def test_tampered_map_is_refused(saved, tamper):
    with h5py.File(saved, 'a') as f:
        tamper(f)
    with pytest.raises(MapFileError, match='content hash'):
        load_map(saved)
    with pytest.raises(MapFileError):
        CapacityMap.load(saved)


def test_tampered_map_refused_by_the_cli_in_one_line(saved, capsys):
    with h5py.File(saved, 'a') as f:
        _one_value(f)
    assert main(['map', 'info', str(saved)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and 'content hash' in err and 'Traceback' not in err


def test_map_without_hash_loads_with_a_loud_warning(saved, capsys):
    with h5py.File(saved, 'a') as f:
        del f.attrs[HASH_ATTR]
    with pytest.warns(MapIntegrityWarning, match=HASH_ATTR):
        data = load_map(saved)
    assert data.integrity == 'unverified'
    # ... and the CLI says so in one warning line, then answers
    assert main(['map', 'info', str(saved)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'warning' in err[0] and HASH_ATTR in err[0]


@pytest.fixture
def shipped_copy(tmp_path, monkeypatch):
    """The shipped maps, copied to a folder that stands in for the installed one."""
    folder = tmp_path / 'installed'
    folder.mkdir()
    for name in SHIPPED.values():
        shutil.copy(maps_dir() / name, folder / name)
    monkeypatch.setenv('RFTGLS_MAPS_DIR', str(folder))
    return folder


def test_shipped_maps_match_the_recorded_hashes():
    for robot, name in SHIPPED.items():
        data = load_map(resolve_map(None, robot))
        assert data.integrity == 'shipped' and data.attrs['robot'] == robot
        assert len(SHIPPED_SHA256[name]) == 64
        assert (maps_dir() / name).stat().st_size < 400_000    # maps stay small


def test_map_info_reports_integrity(capsys):
    import json
    assert main(['map', 'info', SHIPPED['prototype'], '--json']) == 0
    info = json.loads(capsys.readouterr().out)
    assert info['integrity'] == 'shipped'
    assert info['content_sha256'] == SHIPPED_SHA256[SHIPPED['prototype']]


def test_rehashed_tampered_shipped_map_is_refused(shipped_copy):
    path = shipped_copy / SHIPPED['minirquad']
    with h5py.File(path, 'a') as f:
        _double_capacity(f)
    _rehash(path)      # the file's own hash now agrees with the tampered values ...
    with pytest.raises(MapFileError, match='recorded for this shipped map'):
        load_map(path)  # ... but not with the hash recorded in the package
    # The same file outside the installed folder is a user map: its own hash verifies.
    other = shipped_copy.parent / 'elsewhere.h5'
    shutil.copy(path, other)
    assert load_map(other).integrity == 'verified'


def test_resolver_never_searches_the_current_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / 'maps').mkdir()
    planted = tmp_path / 'maps' / SHIPPED['minirquad']
    planted.write_bytes(b'not the shipped map')
    (tmp_path / SHIPPED['minirquad']).write_bytes(b'not the shipped map either')
    installed = maps_dir() / SHIPPED['minirquad']
    for spec in (None, '', 'minirquad', SHIPPED['minirquad'], f'maps/{SHIPPED["minirquad"]}'):
        assert resolve_map(spec, robot='minirquad') == installed
    # An explicit path is used as written.
    mine = save_map(tmp_path / 'mine.h5', synthetic())
    assert resolve_map('./mine.h5').resolve() == mine.resolve()
    assert resolve_map(str(mine)) == mine
    assert resolve_map(f'./{SHIPPED["minirquad"]}').resolve() == \
        (tmp_path / SHIPPED['minirquad']).resolve()
    for bad in ('./missing.h5', str(tmp_path / 'nope.h5')):
        with pytest.raises(MapFileError, match='no such map'):
            resolve_map(bad)
    with pytest.raises(MapFileError, match='no shipped map'):
        resolve_map(None, robot='hexapod')


def test_retired_status_used_at_a_node_is_refused(saved):
    with h5py.File(saved, 'a') as f:
        names = list(f['status'].attrs['status_names'])
        f['status'].attrs['status_names'] = names + ['extrapolated']
        s = f['status'][()]
        s[0, 0, 0, 0, 0, 0] = len(names)
        f['status'][...] = s
        del f.attrs[HASH_ATTR]
    with pytest.raises(MapFileError, match='retired status extrapolated'):
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', MapIntegrityWarning)
            load_map(saved)


def test_legacy_table_with_unused_retired_name_still_reads(saved):
    with h5py.File(saved, 'a') as f:
        f['status'].attrs['status_names'] = ['ok', 'extrapolated'] + [
            n for n in STATUS_NAMES if n != 'ok']
        s = f['status'][()]
        f['status'][...] = np.where(s == 0, 0, s + 1)   # same statuses, old codes
        del f.attrs[HASH_ATTR]
    with pytest.warns(MapIntegrityWarning):
        cmap = CapacityMap.load(saved)
    assert cmap.query(state(10, 0, 20, 20), 0.0, 'backward').status is Status.OK
