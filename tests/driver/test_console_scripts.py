"""The installed executables, started the way ``ros2 run`` starts them."""
from __future__ import annotations

import shutil
import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import JointState


@pytest.mark.slow
@pytest.mark.parametrize('mcu', ['python', 'firmware'])
def test_ros2_run_bridge_node_and_sim(spawn, ros_context, tmp_path, request, mcu):
    ros2 = shutil.which('ros2')
    if ros2 is None:
        pytest.skip('ros2 stand-in not on PATH (source tools/env.sh after make setup)')
    if mcu == 'firmware':
        request.getfixturevalue('firmware_build')
    link = tmp_path / 'tty'
    spawn([ros2, 'run', 'minirquad_sim', 'minirquad_sim', '--symlink', str(link), '--mcu', mcu])
    deadline = time.monotonic() + 30
    while not link.exists():
        assert time.monotonic() < deadline
        time.sleep(0.02)
    bridge = spawn([ros2, 'run', 'minirquad_driver', 'bridge_node',
                    '--ros-args', '-p', f'port:={link}'])
    probe = rclpy.create_node('probe', context=ros_context)
    got: list[JointState] = []
    probe.create_subscription(JointState, 'joint_states', got.append, 100)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    end = time.monotonic() + 15
    while len(got) < 20 and time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    ex.shutdown()
    probe.destroy_node()
    assert len(got) >= 20
    assert bridge.poll() is None      # still running; the fixture stops it
