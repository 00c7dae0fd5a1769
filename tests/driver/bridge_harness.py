"""An in-process bridge node plus a probe node in one executor, for the end-to-end tests."""
from __future__ import annotations

import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import BatteryState, Imu, JointState
from std_msgs.msg import Float64, String

from minirquad_driver.bridge_node import BridgeNode


def stamp_s(msg) -> float:
    """header.stamp of ``msg`` as float seconds."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


class Harness:
    def __init__(self, ctx, port: str, **params):
        overrides = [Parameter('port', value=port), Parameter('diagnostics_period_s', value=0.5)]
        overrides += [Parameter(k, value=v) for k, v in params.items()]
        self.node = BridgeNode(context=ctx, parameter_overrides=overrides)
        self.node.bring_up()
        self.probe = rclpy.create_node('probe', context=ctx)
        self.joints: list[tuple[float, JointState]] = []
        self.joints_wall: list[float] = []      # wall time each joint state was received
        self.energy: list[float] = []
        self.states: list[tuple[float, str]] = []
        self.diag: list[DiagnosticArray] = []
        self.imu: list[Imu] = []
        self.power: list[BatteryState] = []
        self.tension: list[WrenchStamped] = []
        sub = self.probe.create_subscription
        sub(JointState, 'joint_states', self._on_joints, 1000)
        sub(Float64, 'energy', lambda msg: self.energy.append(msg.data), 1000)
        sub(Imu, 'imu/data', self.imu.append, 1000)
        sub(BatteryState, 'power', self.power.append, 1000)
        sub(WrenchStamped, 'winch/tension', self.tension.append, 1000)
        self.winch = self.probe.create_publisher(Float64, 'winch/speed', 10)
        sub(DiagnosticArray, 'diagnostics', self.diag.append, 10)
        # Depth 10: a busy probe must not lose a short-lived state under the next one.
        latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        sub(String, 'minirquad/link_state',
            lambda msg: self.states.append((time.monotonic(), msg.data)), latched)
        self.gait = self.probe.create_publisher(String, 'gait', 10)
        self.executor = SingleThreadedExecutor(context=ctx)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)

    def _on_joints(self, msg: JointState) -> None:
        self.joints.append((time.monotonic(), msg))
        self.joints_wall.append(time.time())

    def published(self, name: str) -> list[tuple[int, dict]]:
        """(level, values) of every /diagnostics status ``name`` received, in order."""
        out = []
        for arr in self.diag:
            for st in arr.status:
                if st.name == name:
                    out.append((st.level[0] if isinstance(st.level, bytes) else int(st.level),
                                {kv.key: kv.value for kv in st.values}))
        return out

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.02)

    def spin_until(self, cond, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            self.executor.spin_once(timeout_sec=0.02)
        return cond()

    def walk(self) -> None:
        assert self.spin_until(lambda: self.joints, 15.0), 'no telemetry'
        self.gait.publish(String(data='walk'))
        assert self.spin_until(lambda: self.node.core.counters.commands_acked >= 1, 3.0)

    def link(self) -> dict:
        return self.node.core.diagnostics(transport=self.node.transport)[0].values

    def close(self) -> None:
        self.node.destroy_node()
        self.probe.destroy_node()
        self.executor.shutdown()
