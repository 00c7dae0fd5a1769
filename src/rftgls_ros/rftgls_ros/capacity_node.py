"""capacity_node: live load capacity, margin and slip twist of the burrowed anchor.

A thin rclpy shell around rftgls_ros.capacity.CapacityEstimator: it parses sensor messages
into SI values, feeds the estimator, and publishes its Estimate. Topics, units and frames are
listed in src/rftgls_ros/README.md. Output frame (`frame_id`, default 'anchor'): world-aligned
axes (x horizontal in the sagittal plane, pointing from p toward the axles; z up) with the
origin at the winch point p, the frame of the architecture page's planar wrenches and twists.

Time: an input's age is judged by its header stamp (the time its sample was taken, on the host
clock), messages without a header (std_msgs/Float64) by their receipt time; parameter
`freshness_source: receipt_time` switches to receipt times for replaying recorded bags whose
stamps are in the past. Inputs, checks and statuses: docs/design/capacity-inputs.md.
"""
from __future__ import annotations

import math
import statistics
import sys
import time
from collections import deque

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped, WrenchStamped
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, String

from rftgls_core.types import Status, pull_direction

from .capacity.estimator import (
    DEFAULT_TIMEOUTS_S,
    JOINTS,
    CapacityEstimator,
    Estimate,
    EstimatorConfig,
)
from .capacity.inputs import gravity_problem, pitch_from_quaternion
from .capacity.predictor import DEFAULT_MAP, ConfigError, make_predictor

NAN = float('nan')
TRIGGERS = ('joint_states', 'pitch', 'tension', 'height', 'phi')
# Diagnostic level per status; anything not listed (a status this node does not expect,
# e.g. the deprecated 'extrapolated') is an ERROR.
LEVELS = {Status.OK: DiagnosticStatus.OK, Status.ASSUMED: DiagnosticStatus.WARN,
          Status.OUT_OF_RANGE: DiagnosticStatus.ERROR,
          Status.UNSUPPORTED: DiagnosticStatus.ERROR, Status.DEGENERATE: DiagnosticStatus.ERROR,
          Status.INVALID_INPUT: DiagnosticStatus.ERROR, Status.STALE: DiagnosticStatus.STALE}
TENSION_AXES = ('x', 'y', 'z', 'tether')
FRESHNESS_SOURCES = ('header_stamp', 'receipt_time')

# name -> default; the type of the default is the parameter type.
PARAMETERS = {
    # predictor
    'map_file': DEFAULT_MAP,          # '' = live computation with live_method
    'live_method': 'direct-warm',     # the cold direct's answers, warm-started per message
    'live_n_twists': 0,               # 0 = rftgls_core default
    'out_of_range_live_method': '',   # '' = none; else the live solver answers off-grid states
    'robot': 'minirquad',
    'medium': 'm90_sand',
    'pull': 'backward',
    # input topics
    'joint_states_topic': '/joint_states',
    'imu_topic': '/imu',
    'pitch_topic': '',                # std_msgs/Float64 theta_B in rad; replaces the IMU if set
    'tension_topic': '/winch/tension',
    # signed tension: force.x (load cell axis; or 'y', 'z'), or 'tether': force . d(phi), a
    # force vector in world axes (the lab bags) projected on the tether direction
    'tension_component': 'x',
    'height_topic': '/winch/height',  # std_msgs/Float64 h in m; '' = parameter height_m only
    'phi_topic': '',                  # std_msgs/Float64 phi in rad; '' = parameter phi_rad only
    'joint_proximal_left': 'leg_proximal_left',
    'joint_proximal_right': 'leg_proximal_right',
    'joint_distal_left': 'leg_distal_left',
    'joint_distal_right': 'leg_distal_right',
    # fallbacks and limits (SI)
    'height_m': 0.03,
    'phi_rad': math.radians(-20.0),
    'leg_tolerance_rad': math.radians(5.0),
    'h_min_m': -0.05,
    'h_max_m': 0.30,
    'tension_max_N': 200.0,
    'tension_deadband_N': 0.05,       # a reading down to -deadband counts as zero
    'imu_tilt_limit_rad': math.radians(80.0),  # body up axis this far from vertical: invalid
    # assumed inputs (height_m, phi_rad without a topic): half-width of the range they may
    # really take; ~/capacity_lower is the smallest capacity over it
    'assumed_height_range_m': 0.01,
    'assumed_phi_range_rad': math.radians(10.0),
    # conservative lower bound on ~/capacity_lower (0 = off; e.g. 0.95)
    'lower_bound_level': 0.0,
    'h_sigma_m': 0.002,
    'theta_b_sigma_rad': math.radians(1.0),
    'capacity_rel_sigma': 0.0,        # e.g. sigma(xi_n)/xi_n from `rftgls calibrate`
    # timing
    **{f'{name}_timeout_s': t for name, t in DEFAULT_TIMEOUTS_S.items()},
    'freshness_source': 'header_stamp',  # or 'receipt_time' (bag replay only)
    'clock_offset_tolerance_s': 0.05,  # stamps up to this far in the future are accepted
    'publish_rate_hz': 20.0,          # minimum output rate (heartbeat when no trigger arrives)
    'trigger_inputs': ['tension'],    # inputs whose every message produces an output
    'diagnostics_period_s': 1.0,
    'frame_id': 'anchor',
}


class CapacityNode(Node):
    """Subscribes to the robot's sensors, publishes capacity, margin, slip twist and status.

    Raises ConfigError from the constructor on a bad parameter or map file.
    """

    def __init__(self, **kwargs):
        super().__init__('capacity_node', **kwargs)
        for name, default in PARAMETERS.items():
            self.declare_parameter(name, default)
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.params = p
        self.estimator = self._make_estimator(p)
        self.frame_id = p['frame_id']
        self.tension_component = p['tension_component']
        if self.tension_component not in TENSION_AXES:
            # 'norm' (|force|) was removed: it turned a -5 N reading into +5 N.
            raise ConfigError(f"tension_component must be the load cell axis 'x', 'y' or 'z', "
                              f"or 'tether' (all signed), got {self.tension_component!r}")
        if p['freshness_source'] not in FRESHNESS_SOURCES:
            raise ConfigError(f'freshness_source must be one of {", ".join(FRESHNESS_SOURCES)}, '
                              f'got {p["freshness_source"]!r}')
        self.use_stamps = p['freshness_source'] == 'header_stamp'
        tilt = p['imu_tilt_limit_rad']
        if not (math.isfinite(tilt) and 0.0 < tilt < math.pi):
            raise ConfigError(f'imu_tilt_limit_rad must lie in (0, pi), got {tilt!r}')
        self.triggers = frozenset(p['trigger_inputs'])
        if not self.triggers <= set(TRIGGERS):
            raise ConfigError(f'trigger_inputs must be a subset of {list(TRIGGERS)}, '
                              f'got {list(p["trigger_inputs"])}')
        rate = p['publish_rate_hz']
        if not (math.isfinite(rate) and rate > 0):
            raise ConfigError(f'publish_rate_hz must be > 0, got {rate!r}')
        if not (math.isfinite(p['diagnostics_period_s']) and p['diagnostics_period_s'] > 0):
            raise ConfigError(f'diagnostics_period_s must be > 0, '
                              f'got {p["diagnostics_period_s"]!r}')
        self.joint_keys = {p[f'joint_{k}']: k for k in JOINTS}

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_capacity = self.create_publisher(WrenchStamped, '~/capacity', 10)
        self.pub_margin = self.create_publisher(WrenchStamped, '~/margin', 10)
        self.pub_lower = self.create_publisher(WrenchStamped, '~/capacity_lower', 10)
        self.pub_twist = self.create_publisher(TwistStamped, '~/slip_twist', 10)
        self.pub_status = self.create_publisher(String, '~/status', latched)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)

        sensor = qos_profile_sensor_data
        self.create_subscription(JointState, p['joint_states_topic'], self.on_joint_states,
                                 sensor)
        if p['pitch_topic']:
            self.create_subscription(Float64, p['pitch_topic'], self.on_pitch, sensor)
        else:
            self.create_subscription(Imu, p['imu_topic'], self.on_imu, sensor)
        self.create_subscription(WrenchStamped, p['tension_topic'], self.on_tension, sensor)
        if p['height_topic']:
            self.create_subscription(Float64, p['height_topic'],
                                     lambda m, i: self.on_scalar('height', m, i), sensor)
        if p['phi_topic']:
            self.create_subscription(Float64, p['phi_topic'],
                                     lambda m, i: self.on_scalar('phi', m, i), sensor)

        self.period_s = 1.0 / rate
        self.last_publish = -math.inf
        self.last_estimate: Estimate | None = None
        self.last_diag_key: tuple | None = None
        self.last_diag_time = -math.inf
        self.processing_s = 0.0
        self.latency_s: deque[float] = deque(maxlen=1000)  # for diagnostics and the bench
        # The timer also keeps the executor waking up, so Ctrl-C / SIGTERM are seen promptly.
        self.create_timer(self.period_s, self.on_timer)
        self.get_logger().info(
            f'predictor {self.estimator.predictor.name}, pull {p["pull"]}, '
            f'triggers {sorted(self.triggers)}, heartbeat {rate:g} Hz, freshness from '
            f'{p["freshness_source"]}')
        cmap = getattr(self.estimator.predictor, 'primary', self.estimator.predictor)
        if getattr(cmap, 'integrity', None) == 'unverified':
            self.get_logger().error(
                f'MAP WITHOUT CONTENT HASH: {cmap.path} cannot be checked for integrity; '
                'answers from it are only as good as the file. Rebuild it with `rftgls map '
                'build` to get a hashed map.')
        for name, topic in (('height', p['height_topic']), ('phi', p['phi_topic'])):
            if not topic:
                self.get_logger().warning(
                    f'{name} is ASSUMED from parameter {name}_{"m" if name == "height" else "rad"}'
                    ' (no topic): every estimate is `assumed`, not `ok`')

    # -- set-up -------------------------------------------------------------------------------
    @staticmethod
    def _make_estimator(p: dict) -> CapacityEstimator:
        timeouts = {name: p[f'{name}_timeout_s'] for name in DEFAULT_TIMEOUTS_S}
        config = EstimatorConfig(
            pull=p['pull'], timeouts_s=timeouts, leg_tolerance_rad=p['leg_tolerance_rad'],
            height_m=p['height_m'], phi_rad=p['phi_rad'], h_range_m=(p['h_min_m'], p['h_max_m']),
            tension_max_N=p['tension_max_N'], tension_deadband_N=p['tension_deadband_N'],
            clock_tolerance_s=p['clock_offset_tolerance_s'],
            assumed_height_range_m=p['assumed_height_range_m'],
            assumed_phi_range_rad=p['assumed_phi_range_rad'],
            lower_bound_level=p['lower_bound_level'],
            h_sigma_m=p['h_sigma_m'], theta_b_sigma_rad=p['theta_b_sigma_rad'],
            capacity_rel_sigma=p['capacity_rel_sigma']).check()
        predictor = make_predictor(p['map_file'], p['live_method'], p['robot'], p['medium'],
                                   p['live_n_twists'], p['pull'], p['out_of_range_live_method'])
        return CapacityEstimator(predictor, config)

    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def sample_time(self, header) -> float:
        """When a message's sample was taken, s on this node's clock: its header stamp
        (freshness_source header_stamp), else (no or zero stamp, or receipt_time) now."""
        if self.use_stamps and header is not None:
            st = header.stamp
            if st.sec != 0 or st.nanosec != 0:
                return st.sec + st.nanosec * 1e-9
        return self.now_s()

    # -- inputs ---------------------------------------------------------------------------------
    def on_joint_states(self, msg: JointState, info) -> None:
        now = self.sample_time(msg.header)
        angles = {}
        for i, name in enumerate(msg.name):
            key = self.joint_keys.get(name)
            if key is None:
                continue
            if i >= len(msg.position):
                self.estimator.mark_malformed('joint_states', now,
                                              f'no position for joint {name!r}')
                self._input_done('joint_states', msg.header.stamp, info)
                return
            angles[key] = msg.position[i]
        if angles:  # messages about other joints only are not ours
            self.estimator.update_joints(now, angles)
            self._input_done('joint_states', msg.header.stamp, info)

    def on_imu(self, msg: Imu, info) -> None:
        now = self.sample_time(msg.header)
        o = msg.orientation
        q = (o.x, o.y, o.z, o.w)
        a = msg.linear_acceleration
        # REP-145: covariance[0] = -1 means the field is not provided.
        accel = None if msg.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
        if msg.orientation_covariance[0] == -1.0:
            self.estimator.mark_malformed('pitch', now, 'IMU publishes no orientation')
        else:
            try:
                why = gravity_problem(q, accel, self.params['imu_tilt_limit_rad'])
                if why is not None:
                    self.estimator.mark_malformed('pitch', now, f'IMU: {why}',
                                                  code='implausible_gravity')
                else:
                    self.estimator.update('pitch', now, pitch_from_quaternion(*q))
            except ValueError as exc:
                self.estimator.mark_malformed('pitch', now, str(exc))
        self._input_done('pitch', msg.header.stamp, info)

    def on_pitch(self, msg: Float64, info) -> None:
        self.estimator.update('pitch', self.now_s(), msg.data)
        self._input_done('pitch', None, info)

    def on_tension(self, msg: WrenchStamped, info) -> None:
        # Signed along the load cell axis: a negative reading stays negative (invalid below the
        # dead band), it is never folded into a positive tension.
        f = msg.wrench.force
        if self.tension_component == 'tether':
            d = pull_direction(self.estimator.current_phi())
            t = f.x * d[0] + f.z * d[1]
        else:
            t = getattr(f, self.tension_component)
        self.estimator.update('tension', self.sample_time(msg.header), t)
        self._input_done('tension', msg.header.stamp, info)

    def on_scalar(self, name: str, msg: Float64, info) -> None:
        self.estimator.update(name, self.now_s(), msg.data)
        self._input_done(name, None, info)

    def _input_done(self, name: str, stamp, info) -> None:
        if name in self.triggers:
            self.publish_estimate(stamp)
            # Input message (its DDS source timestamp, system clock) -> outputs published.
            self.latency_s.append((time.time_ns() - info['source_timestamp']) * 1e-9)

    def on_timer(self) -> None:
        now = time.monotonic()
        if now - self.last_publish >= 0.95 * self.period_s:
            self.publish_estimate(None)
        elif self.last_estimate is not None:
            self._maybe_diagnostics(self.last_estimate)

    # -- outputs --------------------------------------------------------------------------------
    def publish_estimate(self, stamp) -> Estimate:
        """Estimate now and publish every output. stamp: the triggering message's header
        stamp (kept on the outputs so consumers can match them), else the node's clock."""
        t0 = time.perf_counter()
        est = self.estimator.estimate(self.now_s())
        if stamp is None or (stamp.sec == 0 and stamp.nanosec == 0):
            stamp = self.get_clock().now().to_msg()
        phi = est.phi_rad if est.phi_rad is not None else NAN
        d = pull_direction(phi)

        cap = WrenchStamped()
        cap.header.stamp = stamp
        cap.header.frame_id = self.frame_id
        margin = WrenchStamped()
        margin.header = cap.header
        # No value -> NaN, so nobody can read a number as a valid capacity.
        c = est.capacity_N if est.capacity_N is not None else NAN
        m = est.margin_N if est.margin_N is not None else NAN
        cap.wrench.force.x, cap.wrench.force.z = c * d[0], c * d[1]
        margin.wrench.force.x, margin.wrench.force.z = m * d[0], m * d[1]
        if math.isnan(c):
            cap.wrench.force.y = margin.wrench.force.y = NAN
        lower = WrenchStamped()
        lower.header = cap.header
        lo = est.capacity_lower_N if est.capacity_lower_N is not None else NAN
        lower.wrench.force.x, lower.wrench.force.z = lo * d[0], lo * d[1]

        twist = TwistStamped()
        twist.header = cap.header
        if est.slip_twist is None:
            vx = vz = wy = NAN
        elif est.slipping:
            vx, vz, wy = est.slip_twist
        else:  # the anchor holds: predicted motion is zero
            vx = vz = wy = 0.0
        twist.twist.linear.x, twist.twist.linear.z, twist.twist.angular.y = vx, vz, wy

        # The status goes out first, so a consumer that reads it next to a value never sees a
        # value under an older status.
        self.pub_status.publish(String(data=str(est.status)))
        self.pub_capacity.publish(cap)
        self.pub_margin.publish(margin)
        if self.estimator.config.lower_bound_level > 0.0 or est.assumed:
            self.pub_lower.publish(lower)
        self.pub_twist.publish(twist)
        self.last_estimate = est
        self.last_publish = time.monotonic()
        self.processing_s = time.perf_counter() - t0
        self._maybe_diagnostics(est)
        return est

    def _maybe_diagnostics(self, est: Estimate) -> None:
        now = time.monotonic()
        key = (est.status, est.reason, est.warnings)  # a change is reported at once
        if key == self.last_diag_key and \
                now - self.last_diag_time < self.params['diagnostics_period_s']:
            return
        self.last_diag_key = key
        self.last_diag_time = now
        self.pub_diag.publish(self.diagnostics(est))

    def diagnostics(self, est: Estimate) -> DiagnosticArray:
        level = LEVELS.get(est.status, DiagnosticStatus.ERROR)
        if (est.warnings or est.assumed) and level == DiagnosticStatus.OK:
            level = DiagnosticStatus.WARN
        message = str(est.status)
        if est.reason and est.reason != message:
            message += f': {est.reason}'
        if est.warnings:
            message += ' [' + ', '.join(est.warnings) + ']'

        def fmt(x):
            return 'nan' if x is None else f'{x:.6g}'

        st = est.state
        values = {
            'status': str(est.status), 'detail': est.detail,
            'capacity_N': fmt(est.capacity_N), 'capacity_lower_N': fmt(est.capacity_lower_N),
            'tension_N': fmt(est.tension_N),
            'margin_N': fmt(est.margin_N), 'slipping': str(est.slipping).lower(),
            'phi_rad': fmt(est.phi_rad),
            'h_m': fmt(st.h if st else None), 'theta_b_rad': fmt(st.theta_b if st else None),
            'theta_l1_rad': fmt(st.theta_l1 if st else None),
            'theta_l2_rad': fmt(st.theta_l2 if st else None),
            'leg_spread_rad': ('nan' if est.leg_spread_rad is None
                               else ' '.join(f'{x:.4g}' for x in est.leg_spread_rad)),
            'slip_twist': ('nan' if est.slip_twist is None
                           else ' '.join(f'{x:.4g}' for x in est.slip_twist)),
            'assumed_inputs': ','.join(est.assumed), 'stale_inputs': ','.join(est.stale),
            'reason': est.reason,
            'predictor': est.predictor, 'pull': self.params['pull'],
            'freshness_source': self.params['freshness_source'],
            'processing_ms': f'{self.processing_s * 1e3:.3f}',
            'input_to_output_ms_median': (f'{statistics.median(self.latency_s) * 1e3:.3f}'
                                          if self.latency_s else 'nan'),
        }
        stats = getattr(self.estimator.predictor, 'stats', None)   # live direct-warm solver
        if stats is not None:
            values.update({f'solver_{k}': f'{v:.4g}' for k, v in stats().items()})
        status = DiagnosticStatus(level=level, name=f'{self.get_name()}: anchor capacity',
                                  message=message, hardware_id=self.params['robot'],
                                  values=[KeyValue(key=k, value=v) for k, v in values.items()])
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = self.get_clock().now().to_msg()
        return arr


def main(args=None) -> int:
    rclpy.init(args=args)
    node = None
    try:
        node = CapacityNode()
    except (ConfigError, ParameterException) as exc:
        # One clear line, no traceback: a bad parameter or map file is a user error.
        print(f'capacity_node: error: {" ".join(str(exc).split())}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        # spin_once with a timeout, not spin(): see docs/design/ros2-from-pip.md#stopping-nodes.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.2)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
