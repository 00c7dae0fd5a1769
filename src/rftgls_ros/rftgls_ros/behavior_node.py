"""``behavior_node``: walk-burrow-tug, DH/DL/SH chosen on the lower bound (paper section VI), thin
rclpy shell.

The logic is ``rftgls_ros.behavior.BehaviorMachine``; this node converts messages into an
``Observation``, steps the machine (50 Hz and on every capacity output, so the margin guard
reacts at the tension rate), and publishes the commands, the state and every event.

Subscribed: /joint_states (sensor_msgs/JointState: legs rad, ``winch_rope`` m / m/s),
  /imu (sensor_msgs/Imu: thetaB nose up positive, rftgls_conventions.quat_xyzw_to_pitch),
  /winch/tension (geometry_msgs/WrenchStamped, N), /energy (std_msgs/Float64, J),
  /minirquad/link (rftgls_interfaces/LinkState: ok, stale, or untrusted when the bridge counts
  at least 10 % of the MCU's frames lost; both stop a tug), and of capacity_node only its whole
  estimate /capacity_node/estimate (rftgls_interfaces/AnchorEstimate: capacity N along the
  tether, lower bound, status code, assumed inputs, slip twist, in one message). Freshness is
  the age of the underlying sample by its header stamp, not the receipt time
  (docs/design/tug-safety.md, "Freshness by sample age").
Published: /gait/command (rftgls_interfaces/GaitCommand: stand, or walk valid for GAIT_HOLD_S
  and refreshed every step while walking, so the bridge stands the robot when this node
  stops), /burrow (std_msgs/String: a Table II mode's name), /leg_targets
  (sensor_msgs/JointState, rad: a planned gait's leg targets, streamed at the step rate so the
  legs slew at the gait's speed), /winch/command (rftgls_interfaces/WinchCommand: m/s reel-in
  positive; a reel-in carries when its capacity estimate ages out, which the MCU enforces),
  /winch/height_estimate (rftgls_interfaces/InputValue: h of p in m; MiniRQuad does
  not measure it: in a planned gait the burrow simulation's predicted h, MODELLED, with a band
  of two of its standard deviations; in a Table II mode its Table II mean, ASSUMED, band two of
  the paper's standard deviations), /winch/phi (Float64, rad: tether angle from the tether
  length), ~/state (String, transient local), ~/events (String, one JSON object per event).
Action: ~/walk_burrow_tug (rftgls_interfaces/WalkBurrowTug: goal sled mass and cycles, feedback
  state and margin, result per cycle; cancel stops the winch at once; tug_action.py).
  With ``autostart`` (default, kept one release) the node also runs the sled_mass_kg/cycles
  parameters at start, as before the action; ``autostart:=false`` waits for a goal.
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import fields, replace

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, Header, String

from rftgls_conventions import (
    LEG_JOINT_NAMES,
    LEG_KEYS,
    WINCH_ROPE_JOINT,
    axle_angles,
    leg_keys_from_joint_names,
    quat_xyzw_to_pitch,
)
from rftgls_core.planning.replay import inputs_for_map
from rftgls_interfaces.msg import (
    AnchorEstimate,
    GaitCommand,
    InputValue,
    LinkState,
    WinchCommand,
)
from rftgls_node_base.node_main import run_node, stop_requested, usage, wants_help
from rftgls_node_base.parameters import declare
from rftgls_node_base.take_waiting import take_waiting

from .behavior import (
    BehaviorConfig,
    BehaviorMachine,
    ModeChooser,
    Observation,
)
from .behavior.planned import GaitChooser, sled_map
from .behavior.replay import ProcessReplayer
from .behavior.report import write_run_report
from .behavior.tug_series import TugSample, TugSeries
from .capacity.node_predictor import DEFAULT_MAP, node_predictor
from .capacity_msgs import add_estimate, input_value, status_word
from .capacity_query import CAPACITY_SOURCES, ServicePredictor
from .robot_commands import gait_command, winch_command
from .stamps import sample_time
from .tug_action import TugActionServer

EXPIRY_CHECK_S = 0.005  # s: how often a reeling winch's evidence is checked between steps
WINCH_REFRESH_S = 0.02  # s: every 50 Hz control step, well inside the MCU's deadman (80 ms)
# s a walk command stays valid (GaitCommand.valid_until), refreshed at every step: a node that
# stops stepping has the bridge stand the robot this long after its last step. The MCU stops
# the payout that goes with the walk after 80 ms (winch deadman), so a stall longer than that
# walks the robot against a braked tether for up to GAIT_HOLD_S - 0.08 s (~5 mm at the walk's
# 3 cm/s); shorter holds would stand the robot on ordinary step jitter and restart its gait.
GAIT_HOLD_S = 0.25
# joint_states is read best-effort like every sensor stream, but with a history deep enough
# (1 s of the bridge's 100 Hz) that a step running late loses no leg sample: a planned
# burrow's replay follows every measured sample (Observation.leg_samples).
JOINTS_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
# At most this many between two steps (5 s at 100 Hz): the bound that also holds while the
# node idles after a run (no step clears them; the next run's first step sees them outside
# a burrow, where they are not recorded).
LEG_SAMPLES_KEPT = 500
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


# Sanity ranges by unit suffix or name (ROS rejects a value outside them, at start-up too).
_RANGES = {'_m_s': (0.0, 1.0), '_s': (0.0, 3600.0), '_kg': (0.0, 50.0), '_N': (0.0, 1000.0),
           '_J': (0.0, 1e6)}
_RATIOS = ('slow_ratio', 'stop_ratio', 'min_speed_fraction', 'slip_tension_drop', 'need_alpha',
           'sled_mu', 'plan_confidence')


def param_range(name: str) -> tuple[float | None, float | None]:
    """(lo, hi) of a BehaviorConfig parameter, (None, None) without a static range."""
    if name in _RATIOS:
        return 0.0, 1.0
    if name == 'safety_factor':
        return 0.1, 10.0
    return next((r for suffix, r in _RANGES.items() if name.endswith(suffix)), (None, None))


class BehaviorNode(Node):
    def __init__(self, **kwargs):
        super().__init__('behavior_node', **kwargs)
        defaults = BehaviorConfig()
        values = {}
        for f in fields(BehaviorConfig):
            default = getattr(defaults, f.name)
            text = f'BehaviorConfig.{f.name} (src/rftgls_ros/behavior_README.md)'
            if f.name == 'accept_assumed_inputs':
                # A string list as one comma-separated string: an empty list has no ROS type.
                raw = declare(self, f.name, ','.join(default), text)
                values[f.name] = tuple(x.strip() for x in str(raw).split(',') if x.strip())
                continue
            if isinstance(default, tuple):
                default = [float(v) for v in default]
            elif isinstance(default, float):
                default = float(default)
            lo, hi = param_range(f.name)
            values[f.name] = declare(self, f.name, default, text, lo=lo, hi=hi)
        values['phis_rad'] = tuple(values['phis_rad'])
        self.cfg = BehaviorConfig(**values).check()
        self.map_file = declare(self, 'map_file', '', "capacity map; '' = the shipped one")
        self.report_dir = declare(self, 'report_dir', '', "cycle report directory; '' = none")
        self.report_stem = declare(self, 'report_stem', 'cycle_report', 'report file stem')
        self.exit_when_done = declare(self, 'exit_when_done', False, 'exit after the run')
        rate = declare(self, 'step_rate_hz', 50.0, 'state machine step rate', lo=1.0,
                       hi=1000.0)
        cap_ns = declare(self, 'capacity_ns', 'capacity_node',
                         "capacity_node's name (relative: this node's namespace)").rstrip('/')

        # Modes are judged by capacity_node (~/query_capacity, rftgls_ros/capacity_query.py);
        # this node's own map only when configured: capacity_source local_map, or
        # own_capacity_fallback (that fallback is by definition this node's own map).
        source = declare(self, 'capacity_source', 'service',
                         'service = ask capacity_node ~/query_capacity; local_map = own map_file')
        if source not in CAPACITY_SOURCES:
            raise ValueError(f'capacity_source must be one of '
                             f'{", ".join(CAPACITY_SOURCES)}, got {source!r}')
        desc = declare(self, 'anchor_description_file', '',
                       "anchor description YAML of this node's own map (local_map or the "
                       "fallback); '' = the map's robot preset")
        desc_vars = declare(self, 'anchor_state_variables', '',
                            "NAME=ESTIMATE,... feeding the description's variables")
        own_map = source == 'local_map' or self.cfg.own_capacity_fallback
        if (desc or desc_vars) and not own_map:
            raise ValueError("anchor_description_file and anchor_state_variables describe this "
                             "node's own map (capacity_source local_map or "
                             "own_capacity_fallback); with the service, set them on "
                             "capacity_node")
        if own_map:
            predictor = node_predictor(self.map_file or DEFAULT_MAP, robot=None, medium=None,
                                       anchor_description_file=desc,
                                       anchor_state_variables=desc_vars)
        else:
            # A stop request ends a question at once: a mode choice asks dozens in one step.
            predictor = ServicePredictor(self, f'{cap_ns}/query_capacity',
                                         stopping=stop_requested)
        self.predictor = predictor
        self.replayer: ProcessReplayer | None = None
        self.machine = self.new_machine(self.cfg)
        self.obs = Observation(t=self.now_s())
        # Without autostart the node idles (as after a run) until a walk_burrow_tug goal.
        self.finished = not declare(self, 'autostart', True, 'run the sled_mass_kg/cycles '
                                    'parameters at start (deprecated: send a walk_burrow_tug '
                                    'goal); false: wait for a goal')
        self._last_winch: float | None = None
        self._last_winch_t = -math.inf
        self._state_sent: str | None = None

        self.pub_gait = self.create_publisher(GaitCommand, 'gait/command', 10)
        self.pub_burrow = self.create_publisher(String, 'burrow', 10)
        self.pub_legs = self.create_publisher(JointState, 'leg_targets', 10)
        self.pub_winch = self.create_publisher(WinchCommand, 'winch/command', 10)
        self._last_valid_until = 0.0
        # h and phi are a 50 Hz stream of the latest value, read best-effort by capacity_node
        # and state_publisher: best-effort here too (a reliable writer kept nothing better,
        # and after capacity_node was frozen for seconds its samples stopped reaching it for
        # good in the stop campaign: docs/design/tug-safety.md).
        self.pub_height = self.create_publisher(InputValue, 'winch/height_estimate',
                                                qos_profile_sensor_data)
        self.pub_phi = self.create_publisher(Float64, 'winch/phi', qos_profile_sensor_data)
        self.pub_state = self.create_publisher(String, '~/state', LATCHED)
        self.pub_events = self.create_publisher(String, '~/events', 50)

        sensor = qos_profile_sensor_data
        self.create_subscription(JointState, 'joint_states', self.on_joints, JOINTS_QOS)
        self.create_subscription(Imu, 'imu', self.on_imu, sensor)
        self.create_subscription(WrenchStamped, 'winch/tension', self.on_tension, sensor)
        self.create_subscription(Float64, 'energy', self.on_energy, 10)
        self.create_subscription(LinkState, 'minirquad/link', self.on_link, LATCHED)
        # capacity_node: its whole estimate, nothing else (status, value and the names of the
        # assumed inputs arrive together, so they always belong to one estimate).
        self.estimates = self.create_subscription(AnchorEstimate, f'{cap_ns}/estimate',
                                                  self.on_estimate, 10)
        self.expiry_rescued = 0    # expiry checks that found a newer estimate waiting
        # The report's <stem>_tug.png time series (behavior/tug_series.py).
        self.tug_series = TugSeries()
        self.create_timer(1.0 / rate, self.step)
        # While the winch reels, a step the moment the evidence expires, not at the next 50 Hz
        # step: the host's share of the 0.1 s stop budget (docs/design/tug-safety.md).
        self.create_timer(EXPIRY_CHECK_S, self._on_expiry_check)
        self.tug_action = TugActionServer(self, self)
        self.get_logger().info(
            f'sled {1e3 * self.cfg.sled_mass_kg:.0f} g (mu {self.cfg.sled_mu}), {self.cfg.cycles} '
            f'cycles, safety factor {self.cfg.safety_factor}, burrows {self.cfg.burrow_modes}, '
            f'map {predictor.path}; decides on the lower bound; tugs only on capacity_node '
            f'estimates younger than {1e3 * self.cfg.estimate_timeout_s:.0f} ms with status ok'
            + (f' or assumed {",".join(self.cfg.accept_assumed_inputs)}'
               if self.cfg.accept_assumed_inputs else ''))

    def chooser(self, cfg: BehaviorConfig) -> ModeChooser:
        """The chooser of ``burrow_modes``: the paper's modes, or the planner's gaits from the
        gait map of the sled (ValueError, one line, when there is none)."""
        if cfg.burrow_modes == 'planned':
            return GaitChooser(self.predictor, sled_map('minirquad', cfg.sled_mass_kg),
                               cfg.safety_factor, cfg.phis_rad, cfg.plan_confidence)
        return ModeChooser(self.predictor, cfg.safety_factor, cfg.phis_rad)

    def new_machine(self, cfg: BehaviorConfig) -> BehaviorMachine:
        """The behaviour of this configuration; planned burrows get the replay of their
        measured legs (behavior/replay.py: one worker process, kept while its inputs are the
        same gait map's)."""
        chooser = self.chooser(cfg)
        if isinstance(chooser, GaitChooser):
            inputs = inputs_for_map(chooser.gait_map, 'minirquad')
            if self.replayer is None or \
                    self.replayer.inputs.inputs_sha256() != inputs.inputs_sha256():
                if self.replayer is not None:
                    self.replayer.close()
                self.replayer = ProcessReplayer(inputs)
            return BehaviorMachine(cfg, chooser, self.replayer)
        return BehaviorMachine(cfg, chooser)

    def destroy_node(self) -> None:
        # What this node owns goes first, while its handles and the context are still valid:
        # left to the garbage collector (after the context is shut down) the action server and
        # the query's own executor would reach for destroyed handles (a traceback at SIGINT).
        self.tug_action.destroy()
        if self.replayer is not None:
            self.replayer.close()
        if isinstance(self.predictor, ServicePredictor):
            self.predictor.destroy()
        super().destroy_node()

    def now_s(self) -> float:
        return time.monotonic()

    def sample_time(self, stamp) -> float:
        """When a stamped sample was taken, on this node's monotonic clock (s): now minus its
        age by the header stamp (the ROS clock, into which the bridge maps the MCU's sample
        time; stamps.py). A sample that sat in a slow link or a stalled process is as old as
        its stamp says, however recently it arrived."""
        return sample_time(stamp, self.get_clock().now().nanoseconds, self.now_s())

    # ------------------------------------------------------------------ runs (tug_action.py)
    @property
    def running(self) -> bool:
        return not self.finished

    def start_run(self, sled_mass_kg: float, cycles: int) -> None:
        """A new run with this sled (kg) and cycles, the other parameters as configured."""
        lo, hi = _RANGES['_kg']                            # the sled_mass_kg parameter's
        if not (lo < sled_mass_kg <= hi) or cycles < 1:   # NaN fails too
            raise ValueError(f'need 0 < sled_mass_kg <= {hi:g} and cycles >= 1, got '
                             f'{sled_mass_kg!r} kg and {cycles} cycles')
        cfg = replace(self.cfg, sled_mass_kg=float(sled_mass_kg), cycles=int(cycles)).check()
        tether = self.machine.tether      # the same rope: its free length carries over
        self.machine = self.new_machine(cfg)
        self.machine.tether = tether
        self.finished, self._state_sent = False, None

    def stop_run(self, why: str) -> None:
        """Cancel the run and step once: the winch stop is published now."""
        self.machine.cancel(why)
        self.step()

    def latest_estimate(self) -> TugSample | None:
        return self.tug_series.samples[-1] if self.tug_series.samples else None

    # ------------------------------------------------------------------ inputs
    def on_joints(self, msg: JointState) -> None:
        pos = dict(zip(msg.name, msg.position))
        vel = dict(zip(msg.name, msg.velocity))
        t = self.sample_time(msg.header.stamp)
        legs = {key: pos[name] for name, key in leg_keys_from_joint_names(pos).items()}
        if len(legs) == len(LEG_KEYS) and all(math.isfinite(x) for x in legs.values()):
            # Left/right combined on the circle; the machine checks the pose, capacity_node
            # rejects legs that disagree, so no tolerance here (inf).
            axles = axle_angles(legs, math.inf)
            self.obs.legs, self.obs.t_legs = (axles.theta_l1, axles.theta_l2), t
            if len(self.obs.leg_samples) < LEG_SAMPLES_KEPT:
                self.obs.leg_samples.append((t, axles.theta_l1, axles.theta_l2))
        if WINCH_ROPE_JOINT in pos and math.isfinite(pos[WINCH_ROPE_JOINT]):
            self.obs.spool = pos[WINCH_ROPE_JOINT]
            self.obs.spool_velocity = vel.get(WINCH_ROPE_JOINT, 0.0)

    def on_imu(self, msg: Imu) -> None:
        q = msg.orientation
        if msg.orientation_covariance[0] != -1.0:
            try:
                self.obs.theta_b = quat_xyzw_to_pitch(q.x, q.y, q.z, q.w)
            except ValueError:   # zero or non-finite quaternion: keep the last good pitch
                pass

    def on_tension(self, msg: WrenchStamped) -> None:
        if math.isfinite(msg.wrench.force.x):
            self.obs.tension = msg.wrench.force.x
            self.obs.t_tension = self.sample_time(msg.header.stamp)

    def on_energy(self, msg: Float64) -> None:
        self.obs.energy = msg.data

    def on_link(self, msg: LinkState) -> None:
        """The bridge's link state: anything but OK stops a tug (link_wait.py), with its
        reason code; an untrusted link names the loss that made it so."""
        self.obs.link_ok = msg.state == LinkState.OK
        if msg.state == LinkState.UNTRUSTED:
            self.obs.link_fault = 'link_untrusted'
            self.obs.link_detail = (f'{100 * msg.loss_ratio:.0f} % of frames lost over '
                                    f'{msg.loss_window_s:.1f} s')
        elif msg.state != LinkState.OK:
            self.obs.link_fault, self.obs.link_detail = 'link_stale', 'link stale'
        self.step()

    def on_estimate(self, msg: AnchorEstimate) -> None:
        """capacity_node's estimate, as received (judged by the machine's evidence rule).

        Its time is that of its underlying sample: the stamp it carries (its triggering
        tension sample's, or capacity_node's clock for a heartbeat), and never newer than the
        newest tension sample this node has seen, which every estimate is built on: a
        heartbeat over a dead or late link ages with the link's data."""
        self.take_estimate(msg)
        self.step()

    def take_estimate(self, msg: AnchorEstimate) -> None:
        """Put capacity_node's estimate into the observation (on_estimate's doc)."""
        o, t = self.obs, self.now_s()
        sample = self.sample_time(msg.header.stamp)
        if math.isfinite(o.t_tension):
            sample = min(sample, o.t_tension)
        o.capacity, o.t_capacity = msg.capacity_n, sample  # N along the tether; NaN: no value
        o.capacity_lower = msg.capacity_lower_n           # what decisions use; NaN: none
        o.capacity_status = status_word(msg)
        o.assumed_inputs = frozenset(msg.assumed_inputs)
        o.capacity_h = msg.h_m
        o.height_measured = 'height' in msg.measured_inputs
        tw = msg.slip_twist
        twist = (tw.linear.x, tw.linear.z, tw.angular.y)
        # The predicted motion is zero while the anchor holds (capacity_node's slip_twist).
        o.slip_twist = twist if msg.slipping or not all(map(math.isfinite, twist)) \
            else (0.0, 0.0, 0.0)
        add_estimate(self.tug_series, t, msg, str(self.machine.state))

    # ------------------------------------------------------------------ step
    def _on_expiry_check(self) -> None:
        """Step now if the winch reels on an estimate that has just aged past the timeout.
        Estimates already waiting in the queue are taken first: the executor hands this
        timer out before the subscription when both are ready (rftgls_node_base.take_waiting),
        and the newest estimate, not the one before it, is the evidence."""
        if self.finished or not self._last_winch or self._last_winch <= 0.0:
            return
        if self.now_s() - self.obs.t_capacity > self.cfg.estimate_timeout_s:
            waiting = take_waiting(self.estimates)
            for msg in waiting:
                self.take_estimate(msg)
            if waiting and self.now_s() - self.obs.t_capacity <= self.cfg.estimate_timeout_s:
                self.expiry_rescued += 1
            self.step()

    def step(self) -> None:
        if self.finished:
            return
        self.obs.t = self.now_s()
        cmd = self.machine.step(self.obs)
        self.obs.leg_samples = []          # seen by this step
        for topic, value in cmd.oneshots:
            if topic == 'gait':
                self.publish_gait(value)
            else:
                self.pub_burrow.publish(String(data=value))
        if cmd.walking and not any(topic == 'gait' for topic, _ in cmd.oneshots):
            self.publish_gait('walk')       # the refresh (GAIT_HOLD_S)
        t = self.obs.t
        # A moving winch is refreshed every WINCH_REFRESH_S: the MCU's winch deadman stops it
        # when commands stop coming (a stalled or dead node must not keep it reeling).
        # A reel-in also goes out whenever newer evidence moves its deadline (the MCU brakes
        # at the deadline it last received).
        refresh = WINCH_REFRESH_S if cmd.winch != 0.0 else 0.5
        if (self._last_winch is None or abs(cmd.winch - self._last_winch) > 5e-4
                or t - self._last_winch_t > refresh
                or cmd.winch_valid_until > self._last_valid_until):
            self.publish_winch(cmd.winch, cmd.winch_valid_until)
            self._last_winch, self._last_winch_t = cmd.winch, t
        header = Header(stamp=self.get_clock().now().to_msg())
        if cmd.legs is not None:      # a planned burrow: both legs of each axle alike
            l1, l2 = cmd.legs
            pos = {'proximal_left': l1, 'proximal_right': l1, 'distal_left': l2,
                   'distal_right': l2}
            self.pub_legs.publish(JointState(header=header, name=list(LEG_JOINT_NAMES),
                                             position=[float(pos[k]) for k in LEG_KEYS]))
        self.pub_height.publish(input_value(cmd.height, cmd.height_band,
                                            cmd.height_provenance, cmd.height_source, header))
        self.pub_phi.publish(Float64(data=float(cmd.phi)))
        for ev in cmd.events:
            if ev['kind'] == 'warn':
                self.get_logger().warning(f"[warn] {ev['text']}")
            else:
                self.get_logger().info(f"[{ev['kind']}] {ev['text']}")
            self.pub_events.publish(String(data=json.dumps(ev, default=str)))
        state = str(self.machine.state)
        if state != self._state_sent:
            self.pub_state.publish(String(data=state))
            self._state_sent = state
        if self.machine.done:
            self.finish()

    def publish_gait(self, name: str) -> None:
        """A named gait on gait/command; a moving one valid for GAIT_HOLD_S from now."""
        self.pub_gait.publish(gait_command(name, self.get_clock().now().nanoseconds,
                                           GAIT_HOLD_S))

    def publish_winch(self, speed: float, valid_until: float = 0.0) -> None:
        """The winch set-point (m/s) on winch/command, with the time its evidence runs out
        (s on this node's monotonic clock, sent in ROS time; 0: no limit of its own)."""
        self._last_valid_until = valid_until
        self.pub_winch.publish(winch_command(speed, valid_until, self.now_s(),
                                             self.get_clock().now().nanoseconds))

    def finish(self) -> None:
        if self.finished:
            return
        self.finished = True
        self.publish_winch(0.0)
        if self.expiry_rescued:
            self.get_logger().info(
                f'{self.expiry_rescued} evidence checks found a newer estimate waiting in the '
                'queue, taken before judging (rftgls_node_base.take_waiting)')
        self.write_report()

    def write_report(self) -> None:
        """The cycle table and the tug time series with their plots (tables first)."""
        if not (self.report_dir and self.machine.records):
            return
        csv_path, png_path, tug_png = write_run_report(
            self.machine.records, self.tug_series, self.report_dir, self.report_stem,
            self.cfg.slow_ratio, self.cfg.stop_ratio)
        self.get_logger().info(f'cycle report: {csv_path} and {png_path}')
        if tug_png is not None:
            self.get_logger().info(f'tug time series: {tug_png}')


def main(args=None) -> int:
    if wants_help(args):
        print(usage('behavior_node', 'rftgls_ros', __doc__))
        return 0
    done_at: list[float] = []

    def keep_going(node: BehaviorNode) -> bool:
        if node.finished and node.machine.done and node.exit_when_done:
            done_at[:] = done_at or [time.monotonic()]
            return time.monotonic() - done_at[0] <= 0.5   # let the last messages go out
        return True

    def safe_stop(node: BehaviorNode) -> None:
        if not node.finished:
            node.publish_winch(0.0)
            # The cycle in progress (waiting for a link that never came back, say) gets its
            # row with the reason: every cycle leaves one.
            node.machine.close(node.machine.open_reason())
            node.write_report()

    return run_node(BehaviorNode, 'behavior_node', tick=keep_going, on_exit=safe_stop,
                    config_errors=(ValueError,), args=args)


if __name__ == '__main__':
    sys.exit(main())
