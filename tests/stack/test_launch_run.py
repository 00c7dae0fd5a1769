"""Each launch file's programs, started by the project's runner (rftgls_ros.launch_run) with the
command lines launch_ros builds, all stay up for 5 s once every node is on the graph; then the
shutdown launch does (SIGINT to all at once) stops each within 2 s with exit status 0 and no
traceback. bringup publishes /robot_description (the description package's URDF, latched);
in sim.launch.py the winch is commanded to 0 after the SIGINT, before the bridge lets go
(read from the simulator's own log of the host commands it handled)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from rftgls_ros.launch_model import share_dir  # noqa: E402
from rftgls_ros.launch_run import Launch  # noqa: E402

pytestmark = pytest.mark.realtime

REPO = Path(__file__).resolve().parents[2]
SAMPLE_BAG = REPO / 'src/rftgls_ros/rftgls_ros/lab/samples/forward_L1-040_L2+000'
NODES = {'bringup.launch.py': {'bridge_node', 'capacity_node', 'state_publisher',
                               'behavior_node'},
         'sim.launch.py': {'bridge_node', 'capacity_node', 'state_publisher', 'behavior_node'},
         'replay.launch.py': {'rftgls_lab_replay', 'capacity_node', 'state_publisher'}}
BAD_OUTPUT = ('Traceback', 'RCLError', 'context is not valid', 'KeyboardInterrupt')


def launch_file(name: str) -> Path:
    return share_dir('rftgls_ros') / 'launch' / name


class Probe:
    def __init__(self, ctx):
        self.node = rclpy.create_node('launch_probe', context=ctx)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        self.description: list[str] = []
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.node.create_subscription(String, '/robot_description',
                                      lambda m: self.description.append(m.data), latched)

    def spin(self, seconds: float, until=lambda: False) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end and not until():
            self.ex.spin_once(timeout_sec=0.05)
        return bool(until())

    def close(self) -> None:
        self.ex.remove_node(self.node)
        self.node.destroy_node()
        self.ex.shutdown(0.5)


def bring_up(name: str, args: dict, tmp_path: Path, probe: Probe, before_start=None):
    launch = Launch(launch_file(name), args, tmp_path / 'logs')
    if before_start:
        before_start(launch)
    launch.start()
    want = NODES[name]
    try:
        up = probe.spin(45.0, lambda: want <= set(probe.node.get_node_names())
                        or bool(launch.exited()))
        assert up and not launch.exited(), (launch.exited(), probe.node.get_node_names(),
                                            logs(launch))
        t_end = time.monotonic() + 5.0       # every node up: now 5 s of running
        while time.monotonic() < t_end:
            probe.spin(0.1)
            assert not launch.exited(), (launch.exited(), logs(launch))
    except BaseException:
        launch.shutdown(1.0, 1.0)
        raise
    return launch


def logs(launch: Launch) -> dict[str, str]:
    return {r.name: r.log.read_text()[-1500:] for r in launch.running}


def stop_cleanly(launch: Launch) -> dict[str, tuple[int, float]]:
    result = launch.shutdown()
    text = logs(launch)
    for name, (code, seconds) in result.items():
        assert code == 0, (name, code, text[name])
        assert seconds <= 2.0, (name, seconds)
        assert not any(b in text[name] for b in BAD_OUTPUT), (name, text[name])
    return result


@pytest.mark.parametrize('name', sorted(NODES))
def test_launch_file_runs_and_stops_like_ros2_launch(name, tmp_path, ros_context):
    probe = Probe(ros_context)
    log = tmp_path / 'commands.jsonl'
    args = {'bringup.launch.py': {'port': str(tmp_path / 'no_such_tty')},
            'sim.launch.py': {'port': str(tmp_path / 'tty'), 'sled_mass_kg': '1'},
            'replay.launch.py': {'bag': str(SAMPLE_BAG)}}[name]

    def with_command_log(launch: Launch) -> None:
        # The simulator (the hardware stand-in, not under test) logs the commands it handles.
        if name == 'sim.launch.py':
            launch.processes[0].arguments += ['--command-log', str(log)]
    try:
        launch = bring_up(name, args, tmp_path, probe, with_command_log)
        if name != 'replay.launch.py':
            urdf = (share_dir('minirquad_description') / 'urdf' / 'minirquad.urdf').read_text()
            assert probe.spin(5.0, lambda: bool(probe.description))
            assert probe.description[-1] == urdf
        t_sigint = time.time()
        result = stop_cleanly(launch)
        print(name, {n: f'{t:.2f} s' for n, (_, t) in result.items()})
        if name == 'sim.launch.py':
            cmds = [json.loads(x) for x in log.read_text().splitlines() if x.strip()]
            stops = [c for c in cmds if c['command'] == 'WINCH' and c['host_s'] >= t_sigint]
            assert stops and all(c['speed'] == 0.0 for c in stops), cmds[-5:]
    finally:
        probe.close()
