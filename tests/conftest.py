"""Shared test fixtures.

ROS isolation: every pytest process (each xdist worker) reserves its own ROS_DOMAIN_ID for
the whole session by binding a loopback TCP port (32768 + id, the same scheme as ROS 2's
domain_coordinator), so parallel workers and parallel test runs on one machine never see
each other's nodes. DDS discovery is kept on loopback, and the Fast DDS profile
ros2_ws/params/fastdds_localhost.xml binds DDS sockets to 127.0.0.1. Core tests never import
rclpy.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

try:  # the machines are shared and noisy: no per-example time limit on property tests
    from hypothesis import settings as _hypothesis_settings
    _hypothesis_settings.register_profile('rftgls', deadline=None)
    _hypothesis_settings.load_profile('rftgls')
except ImportError:  # pragma: no cover
    pass
_domain_socket: socket.socket | None = None


def _reserve_domain_id() -> int:
    global _domain_socket
    start = 1 + (os.getpid() % 90)
    for k in range(100):
        domain = 1 + (start + k - 1) % 100
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.bind(('127.0.0.1', 32768 + domain))
        except OSError:
            sock.close()
            continue
        _domain_socket = sock
        return domain
    raise RuntimeError('no free ROS domain id in 1..100')


# Fast DDS profile that binds every DDS receive socket to 127.0.0.1 (2.x and 3.x names).
DDS_PROFILE = REPO / 'ros2_ws' / 'params' / 'fastdds_localhost.xml'
DDS_PROFILE_VARS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def pytest_configure(config):
    if os.environ.get('PYTEST_XDIST_WORKER'):
        # Each worker computes on one core: the RFT kernel's parallel loops would otherwise
        # take both cores from the node processes of the other worker's end-to-end tests
        # (seen: a 2.6 s stall of a whole stack mid-tug). Tests that compare thread counts set
        # their own; speed is measured by `rftgls bench`, not here.
        os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')   # before numba starts threads
        try:
            import numba
            numba.set_num_threads(1)
        except ImportError:  # pragma: no cover
            pass
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    for var in DDS_PROFILE_VARS:
        os.environ[var] = str(DDS_PROFILE)
    os.environ.setdefault('MPLBACKEND', 'Agg')
    os.environ['ROS_DOMAIN_ID'] = str(_reserve_domain_id())


@pytest.fixture
def ros_context():
    """A private, initialised rclpy context on this worker's domain (no signal handlers)."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.Context()
    from rftgls_node_base.dds_loopback import during_init
    with during_init():
        rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


def stop_process(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    """terminate -> timed wait -> kill: an rclpy node can ignore SIGTERM
    (see docs/design/ros2-from-pip.md#stopping-nodes)."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout)
        return
    except subprocess.TimeoutExpired:
        pass
    proc.terminate()
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout)


@pytest.fixture
def spawn():
    """Start processes (argv lists) with this worker's ROS environment; always stopped after."""
    procs: list[subprocess.Popen] = []

    def _spawn(argv, **kwargs) -> subprocess.Popen:
        env = dict(os.environ)
        env.update(kwargs.pop('env', {}) or {})
        proc = subprocess.Popen(argv, env=env, **kwargs)
        procs.append(proc)
        return proc

    yield _spawn
    for p in procs:
        stop_process(p)


@pytest.fixture
def stop():
    """stop_process, for tests that stop a process early (e.g. to read its final report)."""
    return stop_process


@pytest.fixture(scope='session')
def firmware_build():
    """The firmware's host build folder (fw_sitl, unit tests, fuzz), made if out of date."""
    from firmware_host import build_host
    return build_host()


@pytest.fixture(scope='session')
def python_exe() -> str:
    return sys.executable


def pytest_unconfigure(config):
    if _domain_socket is not None:
        _domain_socket.close()
