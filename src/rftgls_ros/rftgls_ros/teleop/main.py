"""``teleop``: terminal teleop of the tug with the live prediction (rclpy node + raw tty).

Subscribes /winch/tension, /joint_states (winch_rope), /capacity_node/{capacity, slip_twist,
status}; publishes /winch/speed, /burrow, /gait, /estop, and /winch/height, /winch/phi for
capacity_node (h = Table II mean of the requested mode; phi from the tether length).
Run it alone with the robot (or simulator), bridge_node and capacity_node, not together with
behavior_node (both would command the winch).
"""
from __future__ import annotations

import math
import os
import select
import sys
import termios
import time
import tty

from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String

from minirquad_driver.node_main import run_node, usage, wants_help
from rftgls_core.conventions import WINCH_ROPE_JOINT

from .model import TeleopConfig, TeleopModel

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TeleopNode(Node):
    def __init__(self, **kwargs):
        super().__init__('teleop', **kwargs)
        cfg = TeleopConfig()
        for name in ('step', 'max_speed', 'limit_fraction', 'override_window', 'stale_after',
                     'rope_length', 'attach_height', 'h_stand'):
            setattr(cfg, name, float(self.declare_parameter(name, getattr(cfg, name)).value))
        self.refresh_hz = self.declare_parameter('refresh_hz', 8.0).value
        self.model = TeleopModel(cfg)
        self.pubs = {
            'winch': self.create_publisher(Float64, 'winch/speed', 10),
            'burrow': self.create_publisher(String, 'burrow', 10),
            'gait': self.create_publisher(String, 'gait', 10),
            'estop': self.create_publisher(Bool, 'estop', 10),
        }
        self.pub_h = self.create_publisher(Float64, 'winch/height', 10)
        self.pub_phi = self.create_publisher(Float64, 'winch/phi', 10)
        sensor = qos_profile_sensor_data
        self.create_subscription(WrenchStamped, 'winch/tension', self.on_tension, sensor)
        self.create_subscription(JointState, 'joint_states', self.on_joints, sensor)
        self.create_subscription(WrenchStamped, '/capacity_node/capacity', self.on_capacity, 10)
        self.create_subscription(TwistStamped, '/capacity_node/slip_twist', self.on_twist, 10)
        self.create_subscription(String, '/capacity_node/status', self.on_status, LATCHED)
        self.create_timer(0.05, self.on_timer)

    def send(self, cmds) -> None:
        for topic, value in cmds:
            if topic in ('winch',):
                self.pubs[topic].publish(Float64(data=float(value)))
            elif topic == 'estop':
                self.pubs[topic].publish(Bool(data=bool(value)))
            else:
                self.pubs[topic].publish(String(data=str(value)))

    def on_tension(self, msg) -> None:
        self.model.tension = msg.wrench.force.x

    def on_joints(self, msg) -> None:
        if WINCH_ROPE_JOINT in msg.name:
            self.model.tether.update(msg.position[msg.name.index(WINCH_ROPE_JOINT)])

    def on_capacity(self, msg) -> None:
        self.model.capacity = math.hypot(msg.wrench.force.x, msg.wrench.force.z)
        self.model.t_capacity = time.monotonic()
        self.send(self.model.update(time.monotonic()))

    def on_twist(self, msg) -> None:
        self.model.slip_twist = (msg.twist.linear.x, msg.twist.linear.z, msg.twist.angular.y)

    def on_status(self, msg) -> None:
        self.model.status = msg.data

    def on_timer(self) -> None:
        m = self.model
        self.send(m.update(time.monotonic()))
        if m.winch != 0.0:   # refresh: the MCU's winch deadman stops a winch left unrefreshed
            self.pubs['winch'].publish(Float64(data=float(m.winch)))
        self.pub_h.publish(Float64(data=m.height))
        self.pub_phi.publish(Float64(data=m.tether.phi(m.height)))


def draw(lines: list[str]) -> None:
    sys.stdout.write('\x1b[H\x1b[2J' + '\r\n'.join(lines) + '\r\n')
    sys.stdout.flush()


class Terminal:
    """The raw tty of the teleop session: keys in (non-blocking), the screen redrawn at
    refresh_hz; restores the terminal on close."""

    def __init__(self):
        self.fd = sys.stdin.fileno()
        self.old = termios.tcgetattr(self.fd) if os.isatty(self.fd) else None
        if self.old:
            tty.setcbreak(self.fd)
        self.next_draw = 0.0

    def tick(self, node: TeleopNode) -> bool:
        """Keys to the model, redraw when due; False when the session ends."""
        if node.model.quit:
            return False
        ready, _, _ = select.select([self.fd], [], [], 0)
        if ready:
            data = os.read(self.fd, 32).decode(errors='ignore')
            if not data:
                return False
            for ch in data:
                node.send(node.model.key(ch, time.monotonic()))
            self.next_draw = 0.0
        if time.monotonic() >= self.next_draw:
            draw(node.model.screen())
            self.next_draw = time.monotonic() + 1.0 / max(1.0, node.refresh_hz)
        return True

    def close(self, node: TeleopNode) -> None:
        if self.old:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self.old)
        node.send([('winch', 0.0)])


def main(args=None) -> int:
    if wants_help(args):
        print(usage('teleop', 'rftgls_ros', __doc__))
        return 0
    term = Terminal()
    return run_node(TeleopNode, 'teleop', tick=term.tick, on_exit=term.close,
                    spin_period_s=0.02, args=args)


if __name__ == '__main__':
    sys.exit(main())
