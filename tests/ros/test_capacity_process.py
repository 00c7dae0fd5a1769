"""The installed executable, started the way `ros2 run` starts it (tools/ros2 stand-in, the
colcon install's lib/rftgls_ros/capacity_node), with the shipped YAML parameter file."""
from __future__ import annotations

import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')

from _capacity_common import DH, PHI, Probe  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from rftgls_core.maps import CapacityMap  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
PARAMS = REPO / 'ros2_ws' / 'params' / 'capacity_node.yaml'


def ros2_run(*ros_args):
    ros2 = shutil.which('ros2')
    if ros2 is None:
        pytest.skip('no ros2 on PATH (run `make setup` and source tools/env.sh)')
    return [ros2, 'run', 'rftgls_ros', 'capacity_node', '--ros-args',
            '--params-file', str(PARAMS), '-p', 'phi_topic:=/winch/phi', *ros_args]


@pytest.fixture
def probe(ros_context):
    ex = SingleThreadedExecutor(context=ros_context)
    p = Probe(ros_context, ex, expect_phi=True)
    ex.add_node(p.node)
    yield p
    ex.shutdown()
    p.node.destroy_node()


def test_ros2_run_predicts_and_stops_on_sigterm(spawn, probe, small_map):
    proc = spawn(ros2_run('-p', f'map_file:={small_map}'), stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True)
    probe.wait_matched(timeout=15.0)
    # Inputs at ~100 Hz until an ok output arrives for one of our tension stamps.
    expected = CapacityMap.load(small_map).query(DH, PHI, 'backward').capacity_N
    cap = None
    end = time.monotonic() + 10.0
    while cap is None and time.monotonic() < end:
        probe.state(DH)
        stamp = probe.tension(1.0).header.stamp
        probe.spin_until(lambda: False, 0.01)
        cap = next((m for m in probe.out['capacity'] if m.header.stamp == stamp
                    and probe.last_status() == 'ok'), None)
    assert cap is not None, 'no ok output from the node process'
    d = (-0.9396926207859084, -0.3420201433256687)  # d(phi) for phi = -20 deg
    assert cap.wrench.force.x * d[0] + cap.wrench.force.z * d[1] == pytest.approx(expected)
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(5.0)
    except subprocess.TimeoutExpired:
        pytest.fail('capacity_node ignored SIGTERM for 5 s')


def test_ros2_run_stops_on_ctrl_c(spawn, small_map, probe):
    proc = spawn(ros2_run('-p', f'map_file:={small_map}'), stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True)
    # The heartbeat says stale (no inputs): the node is up and spinning.
    assert probe.spin_until(lambda: probe.last_status() == 'stale', 15.0)
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(5.0)
    except subprocess.TimeoutExpired:
        pytest.fail('capacity_node ignored SIGINT for 5 s')


@pytest.mark.parametrize('args, words', [
    (['-p', 'map_file:=/nonexistent/minirquad.h5'], 'map file not found'),
    (['-p', 'tension_timeout_s:=-1.0'], 'tension'),
    (['-p', 'publish_rate_hz:=20'], 'publish_rate_hz'),  # an int for a double parameter
])
def test_bad_parameter_one_line_and_exit(spawn, args, words, tmp_path):
    proc = spawn(ros2_run(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=20.0)
    except subprocess.TimeoutExpired:
        pytest.fail('capacity_node did not exit on a bad parameter')
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 2
    assert len(lines) == 1 and lines[0].startswith('capacity_node: error:'), err
    assert words in lines[0]


def test_bad_map_schema_one_line(spawn, tmp_path):
    import h5py
    wrong = tmp_path / 'wrong.h5'
    with h5py.File(wrong, 'w') as f:
        f['x'] = [1.0]
    proc = spawn(ros2_run('-p', f'map_file:={wrong}'), stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True)
    _, err = proc.communicate(timeout=20.0)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and 'bad map file' in lines[0], err


def _copy_map(src, dst):
    import shutil as _sh
    _sh.copyfile(src, dst)
    return dst


def test_map_without_content_hash_is_logged_loudly(spawn, tmp_path, small_map):
    import h5py
    path = _copy_map(small_map, tmp_path / 'user_map.h5')
    with h5py.File(path, 'r+') as f:  # a user map as older tools wrote it: no content hash
        for key in [k for k in f.attrs if 'hash' in k.lower() or 'sha256' in k.lower()]:
            del f.attrs[key]
    proc = spawn(ros2_run('-p', f'map_file:={path}'), stdout=subprocess.PIPE,
                 stderr=subprocess.STDOUT, text=True)
    import threading
    lines = []  # read by a thread: a buffered pipe and select() do not mix
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()
    end = time.monotonic() + 20.0
    while time.monotonic() < end and not any('CONTENT HASH' in ln for ln in list(lines)):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    assert any('[ERROR]' in ln and 'MAP WITHOUT CONTENT HASH' in ln for ln in list(lines)), lines


def test_tampered_map_is_refused_with_one_line(spawn, tmp_path, small_map):
    import h5py
    import numpy as np

    assert CapacityMap.load(small_map).data.integrity == 'verified'   # the map carries a hash
    path = _copy_map(small_map, tmp_path / 'tampered.h5')
    with h5py.File(path, 'r+') as f:  # one capacity value changed, nothing else
        cap = f['capacity_N']
        flat = np.array(cap).ravel()
        i = int(np.flatnonzero(np.isfinite(flat) & (flat > 0))[0])
        flat[i] *= 2.0
        cap[...] = flat.reshape(cap.shape)
    proc = spawn(ros2_run('-p', f'map_file:={path}'), stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True)
    _, err = proc.communicate(timeout=20.0)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1, err
    assert lines[0].startswith('capacity_node: error: bad map file'), err
