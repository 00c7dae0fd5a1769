"""DDS stays on loopback: a capacity_node process started the way `ros2 run` starts it,
with this repository's environment (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the Fast DDS
profile ros2_ws/params/fastdds_localhost.xml from tests/conftest.py), has every UDP socket it
holds bound to 127.0.0.1. Read from the kernel's socket table (/proc/<pid>/net/udp, what
`ss -lun` prints) for the node's own pid, and cross-checked with `ss` itself.

The checks can fail: without the profile the same node binds its DDS ports to 0.0.0.0, and a
process that leaves rmw_fastrtps in LOCALHOST mode with the profile (no
rftgls_node_base.dds_loopback) still gets rmw's extra send sockets outside loopback.
Why the profile, not LOCALHOST alone: docs/design/capacity-inputs.md ("DDS on loopback").
"""
from __future__ import annotations

import os
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')

from rftgls_node_base.dds_loopback import profile_problems  # noqa: E402

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
def test_every_dds_socket_of_a_node_is_on_loopback(spawn, env):
    domain = int(os.environ['ROS_DOMAIN_ID'])
    proc = start_node(spawn, env)
    socks = wait_for_dds_sockets(proc, domain)
    assert socks and all(ip == LOOPBACK for ip, _ in socks), socks
    if shutil.which('ss'):
        # The same from `ss -lunp` (UDP sockets, numeric, with their process).
        out = subprocess.run(['ss', '-H', '-lunp'], capture_output=True, text=True,
                             check=True).stdout
        mine = [ln.split()[3] for ln in out.splitlines() if f'pid={proc.pid},' in ln]
        assert mine and all(addr.startswith(LOOPBACK + ':') for addr in mine), out


def test_without_the_profile_the_same_node_listens_on_all_interfaces(spawn):
    domain = int(os.environ['ROS_DOMAIN_ID'])
    proc = start_node(spawn, {}, via_ros2=False)
    socks = wait_for_dds_sockets(proc, domain)
    assert any(ip == '0.0.0.0' and port in dds_ports(domain) for ip, port in socks), socks


PLAIN_LISTENER = r"""
import sys, time, rclpy
from std_msgs.msg import String
rclpy.init()                       # no dds_loopback: rmw_fastrtps's own LOCALHOST handling
node = rclpy.create_node('plain_listener')
got = []
node.create_subscription(String, 'loopback_probe', lambda m: got.append(m.data), 10)
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end and not got:
    rclpy.spin_once(node, timeout_sec=0.1)
print('received' if got else 'nothing', flush=True)
time.sleep(float(sys.argv[2]))     # stay alive so the test can read the socket table
"""


def test_profile_nodes_talk_to_plain_localhost_processes_and_rmw_alone_leaks(spawn,
                                                                              ros_context):
    """A node of the stack (profile applied by dds_loopback) and a process that leaves
    rmw_fastrtps in LOCALHOST mode discover each other on loopback; the latter shows what the
    profile avoids: rmw's own UDPv4 transport holds sockets outside loopback."""
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String
    listener = spawn([sys.executable, '-c', PLAIN_LISTENER, '20', '3'],
                     stdout=subprocess.PIPE, text=True)
    node = rclpy.create_node('loopback_talker', context=ros_context)
    pub = node.create_publisher(String, 'loopback_probe', 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    leaks, line = [], ''
    try:
        end = time.monotonic() + 20
        while time.monotonic() < end and not line:
            pub.publish(String(data='hello'))
            ex.spin_once(timeout_sec=0.1)
            leaks = leaks or [(ip, p) for ip, p in udp_sockets(listener.pid) if ip != LOOPBACK]
            if select.select([listener.stdout], [], [], 0)[0]:
                line = listener.stdout.readline().strip()
    finally:
        ex.remove_node(node)
        node.destroy_node()
    assert line == 'received'
    assert leaks, 'rmw_fastrtps LOCALHOST alone kept every socket on loopback: ' \
                  'dds_loopback may no longer be needed (see its module doc)'


@pytest.mark.parametrize('edit, problem', [
    (('<useBuiltinTransports>false', '<useBuiltinTransports>true'), 'built-in transports'),
    (('<address>127.0.0.1</address>\n        </interfaceWhiteList>',
      '<address>192.0.2.2</address>\n        </interfaceWhiteList>'), 'whitelisted'),
    (('<initialPeersList>\n            <locator><udpv4><address>127.0.0.1',
      '<initialPeersList>\n            <locator><udpv4><address>192.0.2.7'), 'initial peers'),
    (('<builtin>\n', '<builtin>\n          <metatrafficMulticastLocatorList><locator><udpv4>'
      '<address>239.255.0.1</address></udpv4></locator></metatrafficMulticastLocatorList>\n'),
     'metatrafficMulticastLocatorList'),
    (('is_default_profile="true"', 'is_default_profile="false"'), 'default participant'),
    (('<type>SHM</type>', '<type>TCPv4</type>'), 'not UDPv4 or SHM'),
    (('</dds>', ''), 'cannot read'),
])
def test_a_profile_that_is_not_loopback_only_is_not_relied_on(tmp_path, edit, problem):
    """dds_loopback switches rmw's LOCALHOST handling off only for a profile that keeps every
    socket on loopback; each weakening of the shipped profile is named (and the range stays)."""
    from rftgls_node_base.dds_loopback import prepare
    assert profile_problems(DDS_PROFILE) == []
    text = DDS_PROFILE.read_text()
    assert text.count(edit[0]) == 1, edit[0]
    bad = tmp_path / 'profile.xml'
    bad.write_text(text.replace(*edit))
    problems = profile_problems(bad)
    assert any(problem in p for p in problems), problems
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'FASTRTPS_DEFAULT_PROFILES_FILE': str(bad)}
    assert prepare(env).startswith('profile rejected') and \
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'


def test_the_switch_is_for_rclpy_init_only():
    """The exported range stays LOCALHOST for everything but the rclpy.init inside."""
    from rftgls_node_base.dds_loopback import during_init
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
           'FASTRTPS_DEFAULT_PROFILES_FILE': str(DDS_PROFILE)}
    with during_init(env) as what:
        assert (what, env['ROS_AUTOMATIC_DISCOVERY_RANGE']) == ('profile', 'SYSTEM_DEFAULT')
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    for other in ('SUBNET', 'OFF', 'SYSTEM_DEFAULT'):     # a user's explicit choice stands
        env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': other,
               'FASTRTPS_DEFAULT_PROFILES_FILE': str(DDS_PROFILE)}
        with during_init(env) as what:
            assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == other
