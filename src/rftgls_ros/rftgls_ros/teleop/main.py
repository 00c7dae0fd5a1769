"""``teleop``: terminal teleop of the tug with the live prediction (rclpy node + raw tty).

Subscribes /winch/tension, /joint_states (winch_rope), /capacity_node/{capacity, slip_twist,
status}; publishes /winch/speed, /burrow, /gait, /estop, and /winch/height, /winch/phi for
capacity_node (h = Table II mean of the requested mode; phi from the tether length).
Run it alone with the robot (or simulator), bridge_node and capacity_node, not together with
behavior_node (both would command the winch). On exit the session's capacity_node estimates are
written as a time series to `report_dir` (default out/teleop; "" = none): teleop_tug.png/.csv
(tension, capacity, lower bound, guard lines, status; time reeling in shaded as TUG).
"""
from __future__ import annotations

import math
import os
import select
import sys
import termios
import time
import tty

import rclpy
from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String

from ..behavior.tug_series import write_tug_series
from ..capacity_query import record_tug
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
        self.report_dir = self.declare_parameter('report_dir', 'out/teleop').value
        self.tug_series = record_tug(self, '/capacity_node', time.monotonic,
                                     lambda: 'TUG' if self.model.winch > 0.0 else 'manual')

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
        if 'winch_rope' in msg.name:
            self.model.tether.update(msg.position[msg.name.index('winch_rope')])

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


def main(args=None) -> int:
    rclpy.init(args=args)
    node = TeleopNode()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd) if os.isatty(fd) else None
    if old:
        tty.setcbreak(fd)
    period = 1.0 / max(1.0, node.refresh_hz)
    next_draw = 0.0
    try:
        while rclpy.ok() and not node.model.quit:
            executor.spin_once(timeout_sec=0.02)
            ready, _, _ = select.select([fd], [], [], 0)
            if ready:
                data = os.read(fd, 32).decode(errors='ignore')
                if not data:
                    break
                for ch in data:
                    node.send(node.model.key(ch, time.monotonic()))
                next_draw = 0.0
            if time.monotonic() >= next_draw:
                draw(node.model.screen())
                next_draw = time.monotonic() + period
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        try:
            node.send([('winch', 0.0)])
        except Exception:  # noqa: BLE001 - context may be gone
            pass
        if old:
            termios.tcsetattr(fd, termios.TCSADRAIN, old)
        if node.report_dir:
            # The teleop guard: reeling in beyond limit_fraction x C needs the override.
            out = write_tug_series(node.tug_series, node.report_dir, 'teleop', None,
                                   node.model.cfg.limit_fraction,
                                   'teleop session: capacity_node estimates')
            if out:
                print(f'teleop: tug time series {out[1]}')
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
