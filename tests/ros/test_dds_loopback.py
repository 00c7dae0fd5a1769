"""DDS stays on loopback: a capacity_node process started the way `ros2 run` starts it, with
this repository's environment (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the Fast DDS
profile ros2_ws/params/fastdds_localhost.xml from tests/conftest.py), has every socket that
receives DDS traffic bound to 127.0.0.1. Read from the kernel's socket table (/proc/net/udp)
for the node's own pid; the same node without the profile binds them to 0.0.0.0, which shows
the check can fail. What remains outside loopback is documented in
docs/design/capacity-inputs.md ("DDS on loopback") and bounded here.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')

REPO = Path(__file__).resolve().parents[2]
DDS_PROFILE = REPO / 'ros2_ws' / 'params' / 'fastdds_localhost.xml'
DDS_PROFILE_VARS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')
LOOPBACK = '127.0.0.1'


def udp_sockets(pid: int) -> list[tuple[str, int]]:
    """(local address, local port) of every IPv4 UDP socket the process holds."""
    inodes = set()
    for fd in Path(f'/proc/{pid}/fd').iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    out = []
    for line in Path(f'/proc/{pid}/net/udp').read_text().splitlines()[1:]:
        cols = line.split()
        if cols[9] not in inodes:
            continue
        hex_ip, hex_port = cols[1].split(':')
        ip = '.'.join(str(int(hex_ip[i:i + 2], 16)) for i in (6, 4, 2, 0))  # little endian
        out.append((ip, int(hex_port, 16)))
    return out


def dds_ports(domain: int) -> range:
    """The RTPS well-known ports of a domain (PB 7400, DG 250: discovery and user traffic,
    multicast and unicast, for every participant of the domain)."""
    base = 7400 + 250 * domain
    return range(base, base + 250)


NODE_ARGS = ['--ros-args', '-p', 'map_file:=""', '-p', 'live_method:=twist-mesh']


def start_node(spawn, env_overrides: dict, via_ros2: bool = True) -> subprocess.Popen:
    """capacity_node with this worker's ROS environment with the profile variables blank,
    plus env_overrides; through the ros2 stand-in (which applies the profile itself when the
    variable is unset) or as a bare Python module (which does not)."""
    env = {var: '' for var in DDS_PROFILE_VARS}  # spawn() starts from os.environ: blank them
    env.update(env_overrides)
    if via_ros2:
        ros2 = shutil.which('ros2')
        if ros2 is None:
            pytest.skip('no ros2 on PATH (run `make setup` and source tools/env.sh)')
        argv = [ros2, 'run', 'rftgls_ros', 'capacity_node', *NODE_ARGS]
    else:
        argv = [sys.executable, '-m', 'rftgls_ros.capacity_node', *NODE_ARGS]
    return spawn(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                 cwd=REPO)


def wait_for_dds_sockets(proc, domain: int, timeout: float = 15.0) -> list[tuple[str, int]]:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        assert proc.poll() is None, 'capacity_node exited'
        socks = udp_sockets(proc.pid)
        if sum(port in dds_ports(domain) for _, port in socks) >= 2:
            time.sleep(0.5)  # let the participant finish opening its channels
            return udp_sockets(proc.pid)
        time.sleep(0.1)
    pytest.fail('capacity_node opened no DDS sockets')


@pytest.mark.parametrize('env', [{var: str(DDS_PROFILE) for var in DDS_PROFILE_VARS}, {}],
                         ids=['profile_from_environment', 'profile_from_ros2_stand_in'])
def test_node_receives_dds_on_loopback_only(spawn, env):
    domain = int(os.environ['ROS_DOMAIN_ID'])
    proc = start_node(spawn, env)
    socks = wait_for_dds_sockets(proc, domain)
    receiving = [(ip, port) for ip, port in socks if port in dds_ports(domain)]
    assert receiving and all(ip == LOOPBACK for ip, _ in receiving), socks
    # Outside the well-known ports only send sockets remain. rmw_fastrtps adds its own UDPv4
    # transport in LOCALHOST mode (docs/design/capacity-inputs.md): at most its two send
    # sockets (ephemeral ports, one on 0.0.0.0, one per other interface) are not on loopback;
    # their receive channels cannot bind because the profile holds the ports on 127.0.0.1.
    low, _ = map(int, Path('/proc/sys/net/ipv4/ip_local_port_range').read_text().split())
    elsewhere = [(ip, port) for ip, port in socks if ip != LOOPBACK]
    assert all(port >= low and port not in dds_ports(domain) for _, port in elsewhere), socks
    assert len(elsewhere) <= 1 + len(_other_interfaces()), socks


def test_without_the_profile_the_same_node_listens_on_all_interfaces(spawn):
    domain = int(os.environ['ROS_DOMAIN_ID'])
    proc = start_node(spawn, {}, via_ros2=False)
    socks = wait_for_dds_sockets(proc, domain)
    assert any(ip == '0.0.0.0' and port in dds_ports(domain) for ip, port in socks), socks


def _other_interfaces() -> list[str]:
    """Network interfaces other than loopback (/proc/net/dev)."""
    names = [ln.split(':')[0].strip() for ln in
             Path('/proc/net/dev').read_text().splitlines()[2:]]
    return [n for n in names if n != 'lo']
