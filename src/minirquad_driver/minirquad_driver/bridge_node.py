"""``bridge_node``: ROS 2 bridge between the MiniRQuad microcontroller and the stack, a managed
(lifecycle) node.

Thin by design: ``SerialTransport`` moves bytes, ``BridgeCore`` decodes and keeps state,
this node converts samples to messages and commands from messages. Topics, types, units
and frames are tabulated in the package README.

Lifecycle (rclpy.lifecycle; the standard ~/change_state and ~/get_state services):
  configure   opens the serial port (a reader thread that retries until the port appears)
              and starts the heartbeats that feed the MCU's link watchdog;
  activate    starts streaming: samples are published, commands forwarded to the MCU;
  deactivate  commands the winch to 0 and the legs to hold where they are, then stops
              publishing and forwarding (the heartbeats go on: link up, motion stopped);
  cleanup     closes the port; shutdown (also SIGINT/SIGTERM): deactivate, then cleanup.
With `autostart` (default true) the node configures and activates itself, so it runs without
a lifecycle manager (`ros2 run`, `make demo`); false leaves it unconfigured for a manager.

Published (SystemDefaults QoS, depth 10; "latched": reliable + transient local, depth 1):
  joint_states (sensor_msgs/JointState), imu/data (sensor_msgs/Imu, REP-145),
  winch/tension (geometry_msgs/WrenchStamped), power (sensor_msgs/BatteryState),
  power/watts, energy (std_msgs/Float64), minirquad/link (rftgls_interfaces/LinkState,
  latched), /diagnostics (also while inactive).
  Deprecated, kept one release (CHANGELOG.md): imu (= imu/data) and minirquad/link_state
  (std_msgs/String ok|stale, latched).
Every header.stamp is the host-clock time of the MCU sample (see bridge.py and
docs/design/serial-time.md), never the time it was received.
Subscribed (forwarded only while active): winch/command (rftgls_interfaces/WinchCommand),
  gait/command (GaitCommand; a moving gait with valid_until stands the robot when it passes
  unrefreshed, gaits.GaitHold), burrow/command (BurrowCommand), leg_targets (JointState),
  estop (std_msgs/Bool; an engage is forwarded in every configured state).
  Deprecated, one release: winch/speed (std_msgs/Float64, m/s), gait and burrow
  (std_msgs/String names).
"""
from __future__ import annotations

import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from sensor_msgs.msg import BatteryState, Imu, JointState
from std_msgs.msg import Bool, Float64, String

from rftgls_conventions import JOINT_NAMES, LEG_KEYS, pitch_to_quat_xyzw, wrap_angle
from rftgls_interfaces.msg import BurrowCommand, GaitCommand, LinkState, WinchCommand
from rftgls_node_base.node_main import run_node, usage, wants_help
from rftgls_node_base.parameters import declare

from .bridge import (
    BridgeConfig,
    BridgeCore,
    CommandResult,
    PowerSample,
    TelemetrySample,
    winch_command,
)
from .gaits import GAITS, GaitHold
from .protocol import messages as m
from .transport import SerialTransport

# The JointState names of rftgls_conventions, in the MCU's leg order (protocol LEG_NAMES).
assert LEG_KEYS == m.LEG_NAMES, 'protocol leg order must match the shared conventions'
_UNKNOWN_VAR = (math.pi ** 2)    # variance for a quantity the robot does not measure
# GaitCommand's constants -> the named gaits of gaits.py (tests check both ways).
GAIT_OF = {GaitCommand.STAND: 'stand', GaitCommand.WALK: 'walk',
           GaitCommand.REVERSE: 'reverse', GaitCommand.BOUND: 'bound'}
SUCCESS = TransitionCallbackReturn.SUCCESS
STOP_ACK_WAIT_S = 0.3     # on shutdown, how long the winch stop may take to be acknowledged


class BridgeNode(LifecycleNode):
    def __init__(self, **kwargs):
        super().__init__('bridge_node', **kwargs)
        def p(name, default, text, lo=None, hi=None):
            return declare(self, name, default, text, lo=lo, hi=hi)
        self.port = p('port', '/dev/ttyACM0', 'serial device or pyserial URL of the MCU')
        baud = p('baud', 115200, 'serial baud rate', 1200, 4_000_000)
        self.autostart = p('autostart', True, 'configure and activate at start (false: wait '
                           'for a lifecycle manager)')
        self.legacy = p('legacy_topics', True, 'also serve the deprecated topics (imu, '
                        'minirquad/link_state, winch/speed, gait, burrow) for one release')
        self.heartbeat_period_s = p('heartbeat_period_s', 0.1, 'heartbeat period to the MCU '
                                    'watchdog (500 ms on the MCU)', 0.01, 0.45)
        self.pitch_variance = p('pitch_variance_rad2', math.radians(0.5) ** 2,
                                'variance of the IMU pitch', 0.0, 10.0)
        self.imu_frame = p('imu_frame', 'imu_link', 'frame_id of imu/data')
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
                                        'error and makes the link untrusted', 0.0, 1.0),
                           trust_window=p('trust_window_s', 1.0, 'window of the loss that '
                                          'makes the link untrusted', 0.05, 60.0))
        self.core = BridgeCore(cfg)
        self.gait_hold = GaitHold()   # the gait the MCU runs and its deadline (gaits.py)
        self.baud = baud
        self.transport = SerialTransport(
            self.port, baud, self._on_bytes, self._on_connection,
            reconnect_period=p('reconnect_period_s', 0.25, 'retry period of a failed or lost '
                               'port', 0.01, 60.0),
            silence_timeout=p('silence_timeout_s', 1.0, 'silence after which the port is '
                              'reopened', 0.05, 600.0),
            on_open_error=self._on_open_error)
        self.active = False
        self.configured = False

        # Data publishers are managed: they publish only while the node is active.
        pub = self.create_lifecycle_publisher
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_joints = pub(JointState, 'joint_states', 10)
        self.pub_imu = [pub(Imu, 'imu/data', 10)] + ([pub(Imu, 'imu', 10)] if self.legacy
                                                      else [])
        self.pub_tension = pub(WrenchStamped, 'winch/tension', 10)
        self.pub_power = pub(BatteryState, 'power', 10)
        self.pub_watts = pub(Float64, 'power/watts', 10)
        self.pub_energy = pub(Float64, 'energy', 10)
        self.pub_link = pub(LinkState, 'minirquad/link', latched)
        self.pub_state = pub(String, 'minirquad/link_state', latched) if self.legacy else None
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)  # global

        sub = self.create_subscription
        sub(WinchCommand, 'winch/command', self._on_winch_command, 10)
        sub(GaitCommand, 'gait/command', self._on_gait_command, 10)
        sub(BurrowCommand, 'burrow/command', self._on_burrow_command, 10)
        sub(JointState, 'leg_targets', self._on_leg_targets, 10)
        sub(Bool, 'estop', self._on_estop, 10)
        if self.legacy:
            sub(Float64, 'winch/speed', lambda msg: self._motion(m.Winch(msg.data)), 10)
            sub(String, 'gait', lambda msg: self._held_gait(msg.data.strip().lower(), 0.0), 10)
            sub(String, 'burrow', self._on_burrow_name, 10)

        self._state: int | None = None
        self._link_timers: list = []
        # Keeps the executor waking up in every state, so SIGINT/SIGTERM are never missed.
        self.create_timer(p('diagnostics_period_s', 1.0, 'period of /diagnostics', 0.01, 3600.0),
                          self._on_diagnostics)

    def bring_up(self) -> None:
        """configure + activate (what `autostart` does at start)."""
        self.trigger_configure()
        self.trigger_activate()

    # ------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._link_timers = [self.create_timer(self.heartbeat_period_s, self._on_heartbeat),
                        self.create_timer(0.05, self._on_watch)]
        self.transport.start()
        self.configured = True
        self.get_logger().info(f'bridging {self.port} at {self.baud} baud (inactive)')
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        ret = super().on_activate(state)       # enables the managed publishers
        self.active = True
        self._state = None                    # re-publish the link state
        self._publish_state()
        self.get_logger().info('active: streaming and forwarding commands')
        return ret

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self.stop_motion()
        self.get_logger().info('inactive: winch stopped, legs held, commands ignored')
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self._close()
        return SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        if self.active:
            self.active = False
            self.stop_motion(wait_s=STOP_ACK_WAIT_S)
            super().on_deactivate(state)
        self._close()
        return SUCCESS

    def _close(self) -> None:
        self.transport.stop()              # joins the reader thread: nothing publishes after
        self.core.on_connection(False)
        for t in self._link_timers:
            self.destroy_timer(t)
        self._link_timers = []
        self.configured = False

    def destroy_node(self):
        self.transport.stop()
        return super().destroy_node()

    def stop_motion(self, wait_s: float = 0.0) -> bool:
        """The winch to 0 first, then every leg held at its measured angle. With wait_s > 0,
        wait that long for the MCU to acknowledge the winch stop; True when it did (or no wait
        was asked)."""
        self._send(m.Winch(0.0))
        self.gait_hold.left(self.ros_now())
        tel = self.core.last_telemetry
        if tel is not None:
            self._send(m.SetLegs(tuple(wrap_angle(a) for a in tel.leg_angles)))
        end = time.monotonic() + wait_s
        while self.core.awaiting_ack(m.MsgType.WINCH) and self.transport.connected:
            if time.monotonic() >= end:
                return False
            time.sleep(0.01)
        return True

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
        for pub in self.pub_imu:
            pub.publish(imu)

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
        if self.active:
            running = self.gait_hold.running
            if self.gait_hold.due(self.ros_now()) is not None:
                self.get_logger().warning(f'gait {running} not refreshed by its commander '
                                          'before its valid_until: standing')
                self._gait('stand')
        self._publish_state()

    def _publish_state(self) -> None:
        """minirquad/link on every change of state (ok, stale, untrusted), with the loss
        ratio that decided it."""
        word, loss = self.core.link_state()
        state = {'stale': LinkState.STALE, 'untrusted': LinkState.UNTRUSTED}.get(word,
                                                                              LinkState.OK)
        if state != self._state and self.active:
            self._state = state
            msg = LinkState(state=state, loss_ratio=float(loss),
                            loss_window_s=float(self.core.config.trust_window))
            msg.header.stamp = self.get_clock().now().to_msg()
            self.pub_link.publish(msg)
            if self.pub_state is not None:
                self.pub_state.publish(String(data=word))

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
        elif isinstance(msg, (m.SetGait, m.Burrow, m.EStop)):
            # What changes what the robot does, once per command (leg targets and winch
            # speeds stream, and are not): the record of what the MCU was told, beside the
            # commander's own log of why.
            self.get_logger().info(f'to the MCU: {command_text(msg)}')

    def _motion(self, msg) -> None:
        """A motion command: forwarded only while active."""
        if not self.active:
            self.get_logger().warning(f'{type(msg).__name__} ignored: bridge_node is not '
                                      'active', throttle_duration_sec=5.0)
            return
        if not isinstance(msg, (m.SetGait, m.Winch)):
            # legs, burrow, e-stop: the MCU leaves the gait
            self.gait_hold.left(self.ros_now())
        self._send(msg)

    def ros_now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_winch_command(self, msg: WinchCommand) -> None:
        self._motion(winch_command(msg.speed_mps, seconds(msg.valid_until), self.ros_now()))

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
            self.get_logger().error('invalid_input: leg_targets names no known leg')
            return
        self._motion(m.SetLegs(tuple(targets), mask))

    def _on_gait_command(self, msg: GaitCommand) -> None:
        name = GAIT_OF.get(msg.gait)
        if name is None:
            self.get_logger().error(f'invalid_input: unknown GaitCommand.gait {msg.gait}')
            return
        self._held_gait(name, seconds(msg.valid_until), seconds(msg.header.stamp))

    def _held_gait(self, name: str, valid_until: float, sent_at: float = 0.0) -> None:
        """A gait command valid until ``valid_until`` and sent at ``sent_at`` (ROS time, s; 0:
        no limit, unknown): sent unless it refreshes the gait that runs or was sent before the
        MCU was last commanded out of its gait (gaits.GaitHold)."""
        if name not in GAITS:
            self.get_logger().error(f'invalid_input: unknown gait {name!r} '
                                    f'(known: {", ".join(sorted(GAITS))})')
            return
        if not self.active:
            self._motion(GAITS[name])          # ignored, with the warning
            return
        send = self.gait_hold.command(name, valid_until, self.ros_now(), sent_at)
        if send is not None:
            self._gait(send)

    def _gait(self, name: str) -> None:
        self._motion(GAITS[name])

    def _on_burrow_command(self, msg: BurrowCommand) -> None:
        if msg.mode not in tuple(m.BurrowMode):
            self.get_logger().error(f'invalid_input: unknown BurrowCommand.mode {msg.mode}')
            return
        self._motion(m.Burrow(m.BurrowMode(msg.mode)))

    def _on_burrow_name(self, msg: String) -> None:
        name = msg.data.strip().upper()
        if name not in m.BurrowMode.__members__:
            self.get_logger().error(f'invalid_input: unknown burrow mode {msg.data!r}')
            return
        self._motion(m.Burrow(m.BurrowMode[name]))

    def _on_estop(self, msg: Bool) -> None:
        # Engaging only stops motion: honoured in every configured state.
        if msg.data and self.configured:
            self.gait_hold.left(self.ros_now())
            self._send(m.EStop(True))
        else:
            self._motion(m.EStop(bool(msg.data)))


def command_text(msg) -> str:
    """A gait, burrow or e-stop command in a few words (a known gait by its name)."""
    if isinstance(msg, m.SetGait):
        name = next((n for n, g in GAITS.items() if g == msg), None)
        return f'gait {name}' if name else f'gait {m.GaitKind(msg.kind).name.lower()} (custom)'
    if isinstance(msg, m.Burrow):
        return f'burrow {m.BurrowMode(msg.mode).name}'
    return 'e-stop ' + ('engaged' if msg.engage else 'released')


def seconds(stamp) -> float:
    """A builtin_interfaces/Time as float seconds (0.0: the unset stamp)."""
    return stamp.sec + stamp.nanosec * 1e-9


def main(args=None) -> int:
    if wants_help(args):
        print(usage('bridge_node', 'minirquad_driver', __doc__))
        return 0

    def make() -> BridgeNode:
        node = BridgeNode()
        if node.autostart:
            node.bring_up()
        return node

    def safe_stop(node: BridgeNode) -> None:
        # The lifecycle's own shutdown: winch 0 and legs held (acknowledged), port closed.
        node.trigger_shutdown()

    return run_node(make, 'bridge_node', on_exit=safe_stop, args=args)


if __name__ == '__main__':
    sys.exit(main())
