"""A plain (copying, no --symlink-install) colcon build of rftgls_core and rftgls_ros, then
`ros2 run rftgls_ros capacity_node` with the installed parameter file, started outside the
repository: it finds its map (share/rftgls_core/maps) and parameters (share/rftgls_ros/params)
through the ament index, not through the source tree."""
from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_plain_colcon_install_finds_map_and_params(tmp_path, stop):
    if shutil.which('colcon') is None:
        pytest.skip('colcon not installed')
    env = dict(os.environ)
    build = subprocess.run(
        ['colcon', '--log-base', str(tmp_path / 'log'), 'build', '--base-paths',
         *(str(REPO / 'src' / p) for p in ('rftgls_conventions', 'rftgls_core', 'rftgls_ros')),
         '--build-base', str(tmp_path / 'build'), '--install-base', str(tmp_path / 'install')],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    share = tmp_path / 'install' / 'rftgls_ros' / 'share' / 'rftgls_ros'
    assert not (share / 'params').is_symlink()
    params = share / 'params' / 'capacity_node.yaml'
    assert params.is_file() and not params.is_symlink()
    assert (tmp_path / 'install/rftgls_core/share/rftgls_core/maps/minirquad_m90_sand.h5'
            ).is_file()
    # The plain install overlays the workspace: its prefixes come first, like a sourced
    # install/setup.sh; the repository is nowhere on the way (cwd is elsewhere).
    for pkg in ('rftgls_ros', 'rftgls_core'):
        env['AMENT_PREFIX_PATH'] = f'{tmp_path / "install" / pkg}:{env["AMENT_PREFIX_PATH"]}'
        env['PYTHONPATH'] = (f'{tmp_path / "install" / pkg / "lib/python3.11/site-packages"}:'
                             + env.get('PYTHONPATH', ''))
    env.pop('RFTGLS_MAPS_DIR', None)
    cwd = tmp_path / 'elsewhere'
    cwd.mkdir()
    log = cwd / 'node.log'
    with log.open('w') as f:
        # warm_up_solvers off: numba keys its cache on the source's path, and this install's
        # path is new in every run, so the node's warm-up compiled every kernel afresh (16 s of
        # the test's 21 s); the map and parameters it is here for are found before that.
        proc = subprocess.Popen(['ros2', 'run', 'rftgls_ros', 'capacity_node', '--ros-args',
                                 '--params-file', str(params), '-p', 'warm_up_solvers:=false'],
                                cwd=cwd, env=env, stdout=f,
                                stderr=subprocess.STDOUT, text=True)
        try:
            end = time.monotonic() + 60
            while time.monotonic() < end and 'predictor' not in log.read_text() \
                    and proc.poll() is None:
                time.sleep(0.2)
        finally:
            stop(proc)
    text = log.read_text()
    assert 'predictor map:minirquad_m90_sand.h5' in text, text
    out = subprocess.run(
        ['python', '-c', 'import rftgls_core.maps.shipped as s; print(s.__file__); '
                         'print(s.maps_dir())'],
        cwd=cwd, env=env, capture_output=True, text=True, check=True, timeout=60).stdout
    mod, maps = out.split()
    assert mod.startswith(str(tmp_path / 'install')), out
    assert maps == str(tmp_path / 'install/rftgls_core/share/rftgls_core/maps'), out
