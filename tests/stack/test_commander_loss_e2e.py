"""A commander that dies does not leave the robot moving, over real DDS: minirquad_sim on a pty,
bridge_node, capacity_node and behavior_node as processes (test_behavior_e2e.run_stack).

behavior_node is killed (SIGKILL) while it walks the robot. The bridge keeps the MCU's link
watchdog fed, so nothing on the MCU notices; the MCU's winch deadman stops the payout that goes
with the walk. The walk's GaitCommand carried valid_until (0.25 s ahead, refreshed every step),
so the bridge stands the robot: its legs, read on /joint_states as any ROS user would, stop
turning. Before, the robot walked on into the braked tether.
"""
from __future__ import annotations

import math
import re
import signal
import time

import pytest
from test_behavior_e2e import run_stack

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

# Real-time end-to-end stack: `make test` runs it in its real-time phase
# (pytest.ini, Makefile).
pytestmark = [pytest.mark.realtime, pytest.mark.slow]
LEG = 'leg_proximal_left'


class Legs:
    """(monotonic time, proximal-left angle rad) of every /joint_states message."""

    def __init__(self, ctx):
        self.node = rclpy.create_node('commander_loss_probe', context=ctx)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        self.samples: list[tuple[float, float]] = []
        self.node.create_subscription(JointState, 'joint_states', self._on,
                                      qos_profile_sensor_data)

    def _on(self, msg: JointState) -> None:
        if LEG in msg.name:
            self.samples.append((time.monotonic(), msg.position[msg.name.index(LEG)]))

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.02)

    def travel_deg(self, t0: float, t1: float) -> float:
        """Total turning of the leg between t0 and t1 (deg, on the circle)."""
        xs = [x for t, x in self.samples if t0 <= t <= t1]
        return sum(abs(math.degrees(math.remainder(b - a, 2 * math.pi)))
                   for a, b in zip(xs, xs[1:]))

    def close(self) -> None:
        self.ex.remove_node(self.node)
        self.node.destroy_node()


def test_e2e_behavior_node_killed_mid_walk_stands_the_robot(tmp_path, spawn, ros_context):
    legs = Legs(ros_context)      # discovered while the stack starts
    try:
        run_stack(tmp_path, spawn, 0.4, params=['walk_time_s:=8.0'], timeout=60,
                  until=lambda log: re.search(r'-> WALK', log) is not None)
        beh = run_stack.procs['behavior']
        assert beh.poll() is None, (tmp_path / 'behavior.log').read_text()
        legs.spin(1.5)
        now = time.monotonic()
        # Walking (2 s period: 40 deg of stance in 0.84 s, 320 deg of recovery in 1.16 s): at
        # least 84 deg in any second (the whole stance and 0.16 s of recovery).
        assert legs.travel_deg(now - 1.0, now) > 40.0, legs.samples[-5:]
        beh.send_signal(signal.SIGKILL)
        beh.wait(5)
        killed = time.monotonic()
        # The hold (0.25 s), the bridge's 20 Hz watch (0.05 s) and the legs' slew to the
        # nearest standing pose, at most half a turn at the simulator's 8 rad/s walking leg
        # speed (0.39 s): 0.69 s, plus 0.1 s for the command's and the telemetry's way. Then
        # one second in which they must hold. (From 0.5 s, a leg caught half a turn from
        # standing was still slewing: 10.5 deg of travel in a CI run.)
        settle = 0.25 + 0.05 + math.pi / 8.0 + 0.1
        legs.spin(settle + 1.0)
        still = legs.travel_deg(killed + settle, killed + settle + 1.0)
        print(f'leg travel in the second after the stand: {still:.2f} deg')
        assert still < 2.0, legs.samples[-20:]
    finally:
        legs.close()
