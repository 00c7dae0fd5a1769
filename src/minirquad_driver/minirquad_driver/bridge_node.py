"""``bridge_node``: ROS 2 bridge between the MiniRQuad microcontroller and the stack.

Thin by design: ``SerialTransport`` moves bytes, ``BridgeCore`` decodes and keeps state,
this node converts samples to messages and commands from messages. Topics, types, units
and frames are tabulated in the package README.

Published (SystemDefaults QoS, depth 10, except /minirquad/link_state: transient local):
  /joint_states (sensor_msgs/JointState), /imu (sensor_msgs/Imu),
  /winch/tension (geometry_msgs/WrenchStamped), /power (sensor_msgs/BatteryState),
  /power/watts (std_msgs/Float64), /energy (std_msgs/Float64),
  /minirquad/link_state (std_msgs/String: ok|stale), /diagnostics.
Every header.stamp is the host-clock time of the MCU sample (see bridge.py and
docs/design/serial-time.md), never the time it was received.
Subscribed: /leg_targets (JointState), /gait (String), /burrow (String),
  /winch/speed (Float64, m/s), /estop (Bool).
"""
from __future__ import annotations

import math
import sys

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from sensor_msgs.msg import BatteryState, Imu, JointState
from std_msgs.msg import Bool, Float64, String

from rftgls_conventions import JOINT_NAMES, LEG_KEYS, pitch_to_quat_xyzw
from rftgls_node_base.node_main import run_node, usage, wants_help
from rftgls_node_base.parameters import declare

from .bridge import BridgeConfig, BridgeCore, CommandResult, PowerSample, TelemetrySample
from .gaits import GAITS
from .protocol import messages as m
from .transport import SerialTransport

# The JointState names of rftgls_conventions, in the MCU's leg order (protocol LEG_NAMES).
assert LEG_KEYS == m.LEG_NAMES, 'protocol leg order must match the shared conventions'
_UNKNOWN_VAR = (math.pi ** 2)    # variance for a quantity the robot does not measure


class BridgeNode(Node):
    def __init__(self, **kwargs):
        super().__init__('bridge_node', **kwargs)
        def p(name, default, text, lo=None, hi=None):
            return declare(self, name, default, text, lo=lo, hi=hi)
        self.port = p('port', '/dev/ttyACM0', 'serial device or pyserial URL of the MCU')
        baud = p('baud', 115200, 'serial baud rate', 1200, 4_000_000)
        self.heartbeat_period_s = p('heartbeat_period_s', 0.1, 'heartbeat period to the MCU '
                                    'watchdog (500 ms on the MCU)', 0.01, 0.45)
        self.pitch_variance = p('pitch_variance_rad2', math.radians(0.5) ** 2,
                                'variance of the IMU pitch', 0.0, 10.0)
        self.imu_frame = p('imu_frame', 'imu_link', 'frame_id of /imu')
        self.winch_frame = p('winch_frame', 'winch_link', 'frame_id of /winch/tension')
        cfg = BridgeConfig(r_shunt=p('shunt_ohm', 0.1, 'INA219 shunt resistance', 1e-4, 100.0),
                           stale_timeout=p('stale_timeout_s', 0.25, 'newest telemetry older '
                                           'than this (by its stamp): outputs stale', 0.01,
                                           60.0),
                           ack_timeout=p('ack_timeout_s', 0.15, 'command ack wait before a '
                                         'resend', 0.01, 10.0),
                           max_retries=p('max_retries', 3, 'resends per command', 0, 100),
                           energy_max_gap=p('energy_max_gap_s', 0.5, 'largest power sample gap '
                                            'integrated into the energy', 0.01, 60.0),
                           diag_window=p('diag_window_s', 5.0, 'window of the link statistics',
                                         0.1, 3600.0),
                           delay_warn=p('delay_warn_s', 0.1, 'sample age that warns', 0.0,
                                        60.0),
                           delay_error=p('delay_error_s', 0.3, 'sample age that is an error',
                                         0.0, 60.0),
                           loss_warn=p('loss_warn', 0.02, 'frame loss fraction that warns',
                                       0.0, 1.0),
                           loss_error=p('loss_error', 0.10, 'frame loss fraction that is an '
                                        'error', 0.0, 1.0))
        self.core = BridgeCore(cfg)

        self.pub_joints = self.create_publisher(JointState, 'joint_states', 10)
        self.pub_imu = self.create_publisher(Imu, 'imu', 10)
        self.pub_tension = self.create_publisher(WrenchStamped, 'winch/tension', 10)
        self.pub_power = self.create_publisher(BatteryState, 'power', 10)
        self.pub_watts = self.create_publisher(Float64, 'power/watts', 10)
        self.pub_energy = self.create_publisher(Float64, 'energy', 10)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)  # global
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_state = self.create_publisher(String, 'minirquad/link_state', latched)

        self.create_subscription(JointState, 'leg_targets', self._on_leg_targets, 10)
        self.create_subscription(String, 'gait', self._on_gait, 10)
        self.create_subscription(String, 'burrow', self._on_burrow, 10)
        self.create_subscription(Float64, 'winch/speed', self._on_winch, 10)
        self.create_subscription(Bool, 'estop', self._on_estop, 10)

        self._state = None
        self.transport = SerialTransport(
            self.port, baud, self._on_bytes, self._on_connection,
            reconnect_period=p('reconnect_period_s', 0.25, 'retry period of a failed or lost '
                               'port', 0.01, 60.0),
            silence_timeout=p('silence_timeout_s', 1.0, 'silence after which the port is '
                              'reopened', 0.05, 600.0),
            on_open_error=self._on_open_error)
        # These timers also keep the executor waking up, so SIGINT/SIGTERM are never missed.
        self.create_timer(self.heartbeat_period_s, self._on_heartbeat)
        self.create_timer(0.05, self._on_watch)
        self.create_timer(p('diagnostics_period_s', 1.0, 'period of /diagnostics', 0.01, 3600.0),
                          self._on_diagnostics)
        self._publish_state()
        self.transport.start()
        self.get_logger().info(f'bridging {self.port} at {baud} baud')

    def destroy_node(self):
        self.transport.stop()
        return super().destroy_node()

    # ------------------------------------------------------------------ MCU -> ROS
    def _on_connection(self, connected: bool) -> None:
        # Transport thread. Opening a port flushes what the MCU sent before (its reset
        # notice included), so ask for its identity on every connect.
        self.core.on_connection(connected)
        if connected:
            self.transport.write(self.core.command(m.GetInfo()))
        self.get_logger().info('link up' if connected else 'link down: reconnecting')

    def _on_open_error(self, reason: str) -> None:
        # Transport thread; called once per failure episode, not per retry.
        self.core.on_open_error(reason)
        self.get_logger().error(f'cannot open serial port {self.port}: {reason} '
                                f'(retrying every {self.transport.reconnect_period:g} s)')

    def _on_bytes(self, data: bytes, host_time: float) -> None:
        # Runs on the transport's reader thread; rclpy publishers are thread safe.
        for sample in self.core.on_bytes(data, host_time):
            if isinstance(sample, TelemetrySample):
                self._publish_telemetry(sample)
            elif isinstance(sample, PowerSample):
                self._publish_power(sample)
            elif isinstance(sample, CommandResult) and sample.result != m.AckResult.OK:
                self.get_logger().warning(
                    f'command {m.MsgType(sample.type).name} refused: '
                    f'{m.AckResult(sample.result).name}')

    def _publish_telemetry(self, s: TelemetrySample) -> None:
        t = s.telemetry
        stamp = Time(seconds=s.stamp).to_msg()
        js = JointState()
        js.header.stamp = stamp
        js.name = list(JOINT_NAMES)
        js.position = [*t.leg_angles, t.spool_position]
        js.velocity = [*t.leg_velocities, t.spool_velocity]
        self.pub_joints.publish(js)

        imu = Imu()
        imu.header.stamp = stamp
        imu.header.frame_id = self.imu_frame
        # thetaB (nose up) as a body -> world quaternion (rftgls_conventions). Roll and
        # yaw are not measured and set to 0 with a huge variance.
        o = imu.orientation
        o.x, o.y, o.z, o.w = pitch_to_quat_xyzw(t.pitch)
        imu.orientation_covariance = [_UNKNOWN_VAR, 0.0, 0.0, 0.0, self.pitch_variance, 0.0,
                                      0.0, 0.0, _UNKNOWN_VAR]
        imu.angular_velocity.y = -t.pitch_rate
        imu.angular_velocity_covariance = [_UNKNOWN_VAR, 0.0, 0.0, 0.0, 1e-4, 0.0,
                                           0.0, 0.0, _UNKNOWN_VAR]
        imu.linear_acceleration_covariance[0] = -1.0   # REP-145: not provided
        self.pub_imu.publish(imu)

        if t.flags & m.Flag.TENSION_INVALID:
            return    # no fresh load-cell reading: publish no tension rather than an old one
        w = WrenchStamped()
        w.header.stamp = stamp
        w.header.frame_id = self.winch_frame
        w.wrench.force.x = t.tension    # along the tether, pulling p toward the sled
        self.pub_tension.publish(w)

    def _publish_power(self, s: PowerSample) -> None:
        r = s.reading
        b = BatteryState()
        b.header.stamp = Time(seconds=s.stamp).to_msg()
        b.voltage = r.bus_voltage
        # BatteryState: current is negative while discharging; the INA219 reads the
        # current flowing into the robot's load as positive.
        b.current = -r.current
        nan = float('nan')
        b.temperature = b.charge = b.capacity = b.design_capacity = b.percentage = nan
        b.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        b.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_UNKNOWN
        b.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_UNKNOWN
        b.present = True
        self.pub_power.publish(b)
        self.pub_watts.publish(Float64(data=r.power))
        self.pub_energy.publish(Float64(data=s.energy))

    # ------------------------------------------------------------------ timers
    def _on_heartbeat(self) -> None:
        self.transport.write(self.core.heartbeat())

    def _on_watch(self) -> None:
        resend, failed = self.core.due_retries()
        for frame in resend:
            self.transport.write(frame)
        for f in failed:
            self.get_logger().warning(f'command {m.MsgType(f.type).name} seq {f.seq}: no ack')
        self._publish_state()

    def _publish_state(self) -> None:
        state = 'stale' if self.core.is_stale() else 'ok'
        if state != self._state:
            self._state = state
            self.pub_state.publish(String(data=state))

    def _on_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        for d in self.core.diagnostics(self.port, self.transport):
            st = DiagnosticStatus(level=bytes([d.level]), name=d.name, message=d.message,
                                  hardware_id=self.port)
            st.values = [KeyValue(key=k, value='' if v is None else str(v))
                         for k, v in d.values.items()]
            arr.status.append(st)
        self.pub_diag.publish(arr)

    # ------------------------------------------------------------------ ROS -> MCU
    def _send(self, msg) -> None:
        try:
            frame = self.core.command(msg)
        except ValueError as exc:
            self.get_logger().error(f'invalid_input: {type(msg).__name__}: {exc}')
            return
        if not self.transport.write(frame):
            self.get_logger().warning(f'{type(msg).__name__} not sent: link down')

    def _on_leg_targets(self, msg: JointState) -> None:
        targets = [0.0] * 4
        mask = 0
        for name, pos in zip(msg.name, msg.position):
            key = name[4:] if name.startswith('leg_') else name
            if key in m.LEG_NAMES:
                i = m.LEG_NAMES.index(key)
                targets[i] = pos
                mask |= 1 << i
        if not mask:
            self.get_logger().error('invalid_input: /leg_targets names no known leg')
            return
        self._send(m.SetLegs(tuple(targets), mask))

    def _on_gait(self, msg: String) -> None:
        gait = GAITS.get(msg.data.strip().lower())
        if gait is None:
            self.get_logger().error(f'invalid_input: unknown gait {msg.data!r} '
                                    f'(known: {", ".join(sorted(GAITS))})')
            return
        self._send(gait)

    def _on_burrow(self, msg: String) -> None:
        name = msg.data.strip().upper()
        if name not in m.BurrowMode.__members__:
            self.get_logger().error(f'invalid_input: unknown burrow mode {msg.data!r}')
            return
        self._send(m.Burrow(m.BurrowMode[name]))

    def _on_winch(self, msg: Float64) -> None:
        self._send(m.Winch(msg.data))

    def _on_estop(self, msg: Bool) -> None:
        self._send(m.EStop(bool(msg.data)))


def main(args=None) -> int:
    if wants_help(args):
        print(usage('bridge_node', 'minirquad_driver', __doc__))
        return 0
    return run_node(BridgeNode, 'bridge_node', args=args)


if __name__ == '__main__':
    sys.exit(main())
