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
import sys
import time
from collections import deque

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.timer import Timer
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, String

from rftgls_conventions import one_line
from rftgls_core.predictor import predictor_name
from rftgls_core.types import pull_direction
from rftgls_interfaces.msg import AnchorEstimate, InputValue
from rftgls_interfaces.srv import QueryCapacity
from rftgls_node_base.node_main import run_node, usage, wants_help
from rftgls_node_base.parameters import ConfigError, declare

from .capacity.estimator import JOINTS, CapacityEstimator, Estimate
from .capacity.fresh_triggers import FreshTriggers
from .capacity.inputs import frame_problem, imu_problem, quat_xyzw_to_pitch
from .capacity.node_predictor import predictor_from_params, warm_up_predictor
from .capacity.params import PARAMETERS, RUNTIME, configs
from .capacity_msgs import estimate_msg, read_input_value
from .capacity_query import answer_query
from .marker_publisher import CapacityMarkers
from .stamps import is_unset, stamp_s


class CapacityNode(Node):
    """Subscribes to the robot's sensors, publishes capacity, margin, slip twist and status.

    Raises ConfigError from the constructor on a bad parameter or map file.
    """

    def __init__(self, **kwargs):
        super().__init__('capacity_node', **kwargs)
        try:
            p = {name: declare(self, name, spec.default, spec.description, lo=spec.lo,
                               hi=spec.hi, read_only=name not in RUNTIME)
                 for name, spec in PARAMETERS.items()}
        except InvalidParameterValueException as exc:  # outside its range
            raise ConfigError(str(exc)) from exc
        self.params = p
        est_cfg, self.config = configs(p)
        self.estimator = CapacityEstimator(predictor_from_params(p), est_cfg)
        # Compile the live solvers now, not in the first estimate of a tug (node_predictor.py):
        # the node answers nothing until they are ready.
        self.warm_up_s = warm_up_predictor(self.estimator.predictor, p['pull']) \
            if p['warm_up_solvers'] else None
        self.frame_id = p['frame_id']
        self.tension_component = self.config.tension_component
        self.use_stamps = self.config.freshness_source == 'header_stamp'
        self.triggers = self.config.triggers
        rate = self.config.publish_rate_hz
        self.joint_keys = {p[f'joint_{k}']: k for k in JOINTS}

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_capacity = self.create_publisher(WrenchStamped, '~/capacity', 10)
        self.pub_margin = self.create_publisher(WrenchStamped, '~/margin', 10)
        self.pub_lower = self.create_publisher(WrenchStamped, '~/capacity_lower', 10)
        self.pub_twist = self.create_publisher(TwistStamped, '~/slip_twist', 10)
        self.pub_status = self.create_publisher(String, '~/status', latched)
        # /diagnostics is global (every node reports there; REP-107), the rest is relative.
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # The whole estimate in one project-typed message (what behavior_node reads), the
        # "what if" service answered by this node's predictor, and the markers.
        self.pub_estimate = self.create_publisher(AnchorEstimate, '~/estimate', 10)
        self.create_service(QueryCapacity, '~/query_capacity', self.on_query)
        self.markers = CapacityMarkers(self)
        # After every declare (the markers' too): rclpy runs the callback on declarations.
        self.add_on_set_parameters_callback(self.on_set_parameters)

        # Sensor-data QoS (best effort, volatile) with a deeper queue than its 5: at 500 Hz
        # five messages are 10 ms, less than one scheduler hiccup on a busy core, and no input
        # may be lost. A backlog ages: the inputs' stamps still decide `stale`, and a trigger
        # that waited too long is applied without its own answer (fresh_triggers.py).
        sensor = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=p['input_queue_depth'],
                            reliability=ReliabilityPolicy.BEST_EFFORT,
                            durability=DurabilityPolicy.VOLATILE)
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
        if p['height_estimate_topic']:
            self.create_subscription(InputValue, p['height_estimate_topic'],
                                     lambda m, i: self.on_input_value('height', m, i), sensor)
        if p['phi_topic']:
            self.create_subscription(Float64, p['phi_topic'],
                                     lambda m, i: self.on_scalar('phi', m, i), sensor)

        self.period_s = 1.0 / rate
        self.fresh = FreshTriggers(self.config.trigger_max_queue_s)
        # answers a skipped trigger that nothing newer followed (the end of a burst)
        self.catch_up: Timer | None = None
        if self.fresh.max_queue_s > 0.0:
            self.catch_up = self.create_timer(self.fresh.max_queue_s, self.on_catch_up)
            self.catch_up.cancel()
        self.last_publish = -math.inf
        self.last_estimate: Estimate | None = None
        self.last_diag_key: tuple | None = None
        self.last_diag_time = -math.inf
        self.processing_s = 0.0
        # the last 1000 outputs' figures, for /diagnostics (and the bench, which reads them
        # there when the node runs in its own process)
        self.latency_s: deque[float] = deque(maxlen=1000)
        self.processing_window_s: deque[float] = deque(maxlen=1000)
        # The timer also keeps the executor waking up, so Ctrl-C / SIGTERM are seen promptly.
        self.create_timer(self.period_s, self.on_timer)
        self.get_logger().info(
            f'predictor {predictor_name(self.estimator.predictor)}, pull {p["pull"]}, '
            f'triggers {sorted(self.triggers)}, heartbeat {rate:g} Hz, freshness from '
            f'{p["freshness_source"]}'
            + ('' if self.warm_up_s is None else f'; solvers ready ({self.warm_up_s:.1f} s)'))
        cmap = getattr(self.estimator.predictor, 'primary', self.estimator.predictor)
        if getattr(cmap, 'integrity', None) == 'unverified':
            self.get_logger().error(
                f'MAP WITHOUT CONTENT HASH: {cmap.path} cannot be checked for integrity; '
                'answers from it are only as good as the file. Rebuild it with `rftgls map '
                'build` to get a hashed map.')
        for name, topic in (('height', p['height_topic'] or p['height_estimate_topic']),
                            ('phi', p['phi_topic'])):
            if not topic:
                self.get_logger().warning(
                    f'{name} is ASSUMED from parameter {name}_{"m" if name == "height" else "rad"}'
                    ' (no topic): every estimate is `assumed`, not `ok`')

    # -- parameters -----------------------------------------------------------------------
    def on_set_parameters(self, params) -> SetParametersResult:
        """A run-time change of RUNTIME parameters: validated as a whole, then applied to the
        estimator and the node (the next estimate uses it), or rejected with the reason.
        Read-only (start-up) parameters never get here: rclpy rejects them first."""
        proposed = {**self.params, **{x.name: x.value for x in params}}
        try:
            est_cfg, node_cfg = configs(proposed)
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=one_line(exc))
        self.estimator.reconfigure(est_cfg)
        self.params, self.config = proposed, node_cfg
        self.get_logger().info('parameters changed: ' + ', '.join(
            f'{x.name}={x.value!r}' for x in params))
        return SetParametersResult(successful=True)

    def on_query(self, req, res):
        return answer_query(self.estimator.predictor, self.params['pull'], req, res,
                            self.estimator.asked.bound)

    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def sample_time(self, header) -> float:
        """When a message's sample was taken, s on this node's clock: its header stamp
        (freshness_source header_stamp), else (no or zero stamp, or receipt_time) now."""
        if self.use_stamps and header is not None and not is_unset(header.stamp):
            return stamp_s(header.stamp)
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
        # Judged on the raw message (frame, quaternion norm, roll, gravity), before the
        # quaternion is normalised into a pitch: docs/design/capacity-inputs.md.
        now = self.sample_time(msg.header)
        o = msg.orientation
        q = (o.x, o.y, o.z, o.w)
        a = msg.linear_acceleration
        # REP-145: covariance[0] = -1 means the field is not provided.
        accel = None if msg.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
        cfg = self.config
        wrong_frame = frame_problem(msg.header.frame_id, cfg.imu_frame_id)
        if wrong_frame is not None:
            self.estimator.mark_malformed('pitch', now, f'IMU: {wrong_frame}', code='wrong_frame')
        elif msg.orientation_covariance[0] == -1.0:
            self.estimator.mark_malformed('pitch', now, 'IMU publishes no orientation')
        else:
            problem = imu_problem(q, accel, cfg.imu_tilt_limit_rad, cfg.imu_roll_limit_rad)
            if problem is not None:
                self.estimator.mark_malformed('pitch', now, f'IMU: {problem[1]}',
                                              code=problem[0])
            else:
                self.estimator.update('pitch', now, quat_xyzw_to_pitch(*q))
        self._input_done('pitch', msg.header.stamp, info)

    def on_pitch(self, msg: Float64, info) -> None:
        self.estimator.update('pitch', self.now_s(), msg.data)
        self._input_done('pitch', None, info)

    def on_tension(self, msg: WrenchStamped, info) -> None:
        # Signed along the load cell axis: a negative reading stays negative (invalid below the
        # dead band), it is never folded into a positive tension.
        wrong_frame = frame_problem(msg.header.frame_id, self.config.tension_frame_id)
        if wrong_frame is not None:
            self.estimator.mark_malformed('tension', self.sample_time(msg.header),
                                          f'tension: {wrong_frame}', code='wrong_frame')
            self._input_done('tension', msg.header.stamp, info)
            return
        f = msg.wrench.force
        if self.tension_component == 'tether':
            d = pull_direction(self.estimator.current_phi())
            t = f.x * d[0] + f.z * d[1]
        else:
            t = getattr(f, self.tension_component)
        self.estimator.update('tension', self.sample_time(msg.header), t)
        self._input_done('tension', msg.header.stamp, info)

    def on_scalar(self, name: str, msg: Float64, info) -> None:
        """A bare Float64: a measurement (it has no way to say otherwise)."""
        self.estimator.update(name, self.now_s(), msg.data)
        self._input_done(name, None, info)

    def on_input_value(self, name: str, msg: InputValue, info) -> None:
        """A value with its band and provenance: carried into the estimate (status assumed,
        or ok naming the modelled input, the lower bound covering the band)."""
        t = self.sample_time(msg.header)
        got = read_input_value(msg)
        if isinstance(got, str):
            self.estimator.mark_malformed(name, t, f'{name}: {got}')
        else:
            self.estimator.update(name, t, *got)
        self._input_done(name, msg.header.stamp, info)

    def _input_done(self, name: str, stamp, info) -> None:
        if name not in self.triggers:
            return
        source_ns = info['source_timestamp']   # DDS source time, system clock
        if self.fresh.arrived((time.time_ns() - source_ns) * 1e-9, stamp, source_ns):
            if self.catch_up is not None:
                self.catch_up.cancel()
            self._answer(stamp, source_ns)
        elif self.catch_up is not None:
            self.catch_up.reset()

    def on_catch_up(self) -> None:
        assert self.catch_up is not None   # the timer exists only when skipping is on
        self.catch_up.cancel()
        pending = self.fresh.take_pending()
        if pending is not None:
            self._answer(pending.stamp, pending.source_ns)

    def _answer(self, stamp, source_ns: int) -> None:
        self.publish_estimate(stamp)
        # Input message (its DDS source timestamp, system clock) -> outputs published.
        self.latency_s.append((time.time_ns() - source_ns) * 1e-9)
        # Between two triggers: one prediction toward the next tether angle's lower bound,
        # so that bound is ready before the creeping angle needs it (lower_bound.py).
        self.estimator.prefetch()

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
        out = self.estimator.outputs(est)
        if stamp is None or is_unset(stamp):
            stamp = self.get_clock().now().to_msg()
        cap, margin, lower = WrenchStamped(), WrenchStamped(), WrenchStamped()
        cap.header.stamp = stamp
        cap.header.frame_id = self.frame_id
        margin.header = lower.header = cap.header
        cap.wrench.force.x, cap.wrench.force.z = out.capacity_xz
        margin.wrench.force.x, margin.wrench.force.z = out.margin_xz
        cap.wrench.force.y = margin.wrench.force.y = out.capacity_y
        lower.wrench.force.x, lower.wrench.force.z = out.lower_xz
        twist = TwistStamped()
        twist.header = cap.header
        twist.twist.linear.x, twist.twist.linear.z, twist.twist.angular.y = out.slip_twist

        # The status goes out first, so a consumer that reads it next to a value never sees a
        # value under an older status.
        self.pub_status.publish(String(data=out.status))
        self.pub_capacity.publish(cap)
        self.pub_margin.publish(margin)
        if out.publish_lower:
            self.pub_lower.publish(lower)
        self.pub_twist.publish(twist)
        self.pub_estimate.publish(estimate_msg(est, cap.header, self.params['pull']))
        self.markers.publish(est, cap.header)
        self.last_estimate = est
        self.last_publish = time.monotonic()
        self.processing_s = time.perf_counter() - t0
        self.processing_window_s.append(self.processing_s)
        self._maybe_diagnostics(est)
        return est

    def _maybe_diagnostics(self, est: Estimate) -> None:
        now = time.monotonic()
        key = (est.status, est.reason, est.warnings)  # a change is reported at once
        if key == self.last_diag_key and \
                now - self.last_diag_time < self.config.diagnostics_period_s:
            return
        self.last_diag_key = key
        self.last_diag_time = now
        self.pub_diag.publish(self.diagnostics(est))

    def diagnostics(self, est: Estimate) -> DiagnosticArray:
        d = self.estimator.diagnostic(est, f'{self.get_name()}: anchor capacity', {
            'freshness_source': self.params['freshness_source'],
            'processing_ms': f'{self.processing_s * 1e3:.3f}',
            'processing_ms_median': _ms(self.processing_window_s, 0.5),
            'input_to_output_ms_median': _ms(self.latency_s, 0.5),
            'input_to_output_ms_p99': _ms(self.latency_s, 0.99),
            'triggers_skipped': str(self.fresh.skipped),
        })
        stats = getattr(self.estimator.predictor, 'stats', None)   # live direct-warm solver
        values = dict(d.values)
        if stats is not None:
            values.update({f'solver_{k}': f'{v:.4g}' for k, v in stats().items()})
        status = DiagnosticStatus(level=bytes([d.level]), name=d.name, message=d.message,
                                  hardware_id=self.params['robot'],
                                  values=[KeyValue(key=k, value=v) for k, v in values.items()])
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = self.get_clock().now().to_msg()
        return arr


def _ms(window_s, q: float) -> str:
    """The q-quantile (nearest rank) of a window of durations in s, as ms text ('nan' empty)."""
    if not window_s:
        return 'nan'
    v = sorted(window_s)
    return f'{v[min(len(v) - 1, max(0, math.ceil(q * len(v)) - 1))] * 1e3:.3f}'


def main(args=None) -> int:
    if wants_help(args):
        print(usage('capacity_node', 'rftgls_ros', __doc__,
                    {n: spec.default for n, spec in PARAMETERS.items()}))
        return 0
    return run_node(CapacityNode, 'capacity_node', config_errors=(ConfigError,), args=args,
                    spin_period_s=0.2)


if __name__ == '__main__':
    sys.exit(main())
