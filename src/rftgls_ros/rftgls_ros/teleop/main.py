"""``teleop``: terminal teleop of the tug with the live prediction (rclpy node + raw tty).

Subscribes /winch/tension, /joint_states (winch_rope) and /capacity_node/estimate (status,
capacity, its lower bound, slip twist and the assumed inputs in one message, so they never mix
two estimates; the guard decides on the lower bound);
publishes /winch/command (rftgls_interfaces/WinchCommand: a reel-in carries the time its
estimate goes stale, so the MCU brakes then even if teleop stalls), /gait/command
(GaitCommand: a walk refreshed at 20 Hz with valid_until 0.5 s ahead, so the robot stands if
teleop dies), /burrow, /estop, and
for capacity_node /winch/height_estimate
(rftgls_interfaces/InputValue: after a burrow the burrow simulation's h for that mode and the
sled it is tied to (sled_mass_kg), MODELLED with its band; standing h_stand_m, ASSUMED;
teleop/anchor.py) and /winch/phi (from the tether paid out and the attachment height:
rftgls_ros.tether.TetherTracker, the one behavior_node uses). capacity_node's estimate of a
burrowed anchor is therefore `ok` with provenance `height:modelled`. Once the legs hold the
final pose, a measured pitch outside the modelled pitch's band is flagged (screen, log) and h
is sent ASSUMED until the next burrow: `assumed (height)`, refused unless accepted
(`-p accept_assumed_inputs:=height`, the same opt-in as behavior_node's).
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

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Header, String

from rftgls_conventions import LEG_JOINT_NAMES, LEG_KEYS, WINCH_ROPE_JOINT, axle_angles
from rftgls_core.planning.burrowed import mode_pose
from rftgls_interfaces.msg import AnchorEstimate, GaitCommand, InputValue, WinchCommand
from rftgls_node_base.node_main import run_node, usage, wants_help
from rftgls_node_base.parameters import declare

from ..behavior.tug_series import write_tug_series
from ..capacity_msgs import input_value, record_tug
from ..robot_commands import gait_command, winch_command
from ..stamps import sample_time
from .anchor import LEG_TOLERANCE_RAD
from .model import TeleopConfig, TeleopModel

# ROS parameter (unit in the name) -> (TeleopConfig field, meaning, lo, hi). Start-up only.
PARAMETERS = {
    'step_m_s': ('step', 'winch speed change per key press', 0.0, 1.0),
    'max_speed_m_s': ('max_speed', 'largest winch speed', 0.0, 1.0),
    'limit_fraction': ('limit_fraction', 'tension/lower bound beyond which pulling needs the '
                       'override', 0.0, 1.0),
    'override_window_s': ('override_window', 'time the override stays armed', 0.0, 600.0),
    'stale_after_s': ('stale_after', 'capacity output age that is not valid', 0.0, 60.0),
    'rope_length_m': ('rope_length', 'tether paid out at start (for phi)', 0.0, 100.0),
    'attach_height_m': ('attach_height', 'tether attachment height on the sled', -1.0, 1.0),
    'h_stand_m': ('h_stand', 'height of p when not burrowed', -1.0, 1.0),
    'sled_mass_kg': ('sled_mass', 'sled the robot burrows tied to (picks the gait map of the '
                     'modelled burrowed pose)', 0.0, 50.0),
}
MODES = ('DH', 'DL', 'SH')
# s a walk stays valid without a refresh (on_timer refreshes it at 20 Hz): teleop gone, the
# bridge stands the robot within this.
GAIT_HOLD_S = 0.5


def modelled_poses(sled_kg: float) -> dict:
    """Each mode's modelled burrowed pose for the sled, or why there is none (one line)."""
    out: dict = {}
    for mode in MODES:
        try:
            out[mode] = mode_pose(mode, sled_kg) or f'{mode}: the burrow simulation has no pose'
        except ValueError as exc:
            out[mode] = str(exc)
    return out


class TeleopNode(Node):
    def __init__(self, **kwargs):
        super().__init__('teleop', **kwargs)
        cfg = TeleopConfig()
        for name, (field, text, lo, hi) in PARAMETERS.items():
            setattr(cfg, field, float(declare(self, name, float(getattr(cfg, field)), text,
                                              lo=lo, hi=hi)))
        accept = declare(self, 'accept_assumed_inputs', '',
                         "inputs an 'assumed' estimate may assume, comma-separated (e.g. "
                         "'height'); '' = none: only a measured ok is evidence")
        cfg.accept_assumed_inputs = tuple(x.strip() for x in str(accept).split(',')
                                          if x.strip())
        self.refresh_hz = declare(self, 'refresh_hz', 8.0, 'screen refresh rate', lo=0.1,
                                  hi=100.0)
        self.model = TeleopModel(cfg, modelled_poses(cfg.sled_mass))
        for mode, pose in self.model.anchor.poses.items():
            self.get_logger().info(f'{mode}: ' + (
                pose if isinstance(pose, str) else
                f'h {1e3 * pose.h_m:.1f} +- {1e3 * pose.h_band_m:.1f} mm, pitch '
                f'{math.degrees(pose.theta_b_rad):.1f} +- '
                f'{math.degrees(pose.theta_b_band_rad):.1f} deg ({pose.source})'))
        self.walking = False   # the last gait sent was walk (refreshed while so)
        self.pubs = {
            'winch': self.create_publisher(WinchCommand, 'winch/command', 10),
            'burrow': self.create_publisher(String, 'burrow', 10),
            'gait': self.create_publisher(GaitCommand, 'gait/command', 10),
            'estop': self.create_publisher(Bool, 'estop', 10),
        }
        self.pub_h = self.create_publisher(InputValue, 'winch/height_estimate', 10)
        self.pub_phi = self.create_publisher(Float64, 'winch/phi', 10)
        sensor = qos_profile_sensor_data
        self.create_subscription(WrenchStamped, 'winch/tension', self.on_tension, sensor)
        self.create_subscription(JointState, 'joint_states', self.on_joints, sensor)
        self.create_subscription(AnchorEstimate, 'capacity_node/estimate', self.on_estimate,
                                 10)
        self.create_timer(0.05, self.on_timer)
        self.report_dir = declare(self, 'report_dir', 'out/teleop',
                                  "session time series directory; '' = none")
        self.tug_series = record_tug(self, 'capacity_node', time.monotonic,
                                     lambda: 'TUG' if self.model.winch > 0.0 else 'manual')

    def send(self, cmds) -> None:
        unheard = dict.fromkeys(self.pubs[t].topic_name for t, _ in cmds
                                if self.pubs[t].get_subscription_count() == 0)
        if unheard:   # a lost command must not look like a sent one
            self.model.message += (f'; NOT SENT: nobody subscribes to {", ".join(unheard)} '
                                   '(is bridge_node running?)')
            self.model.alert = True
        for topic, value in cmds:
            if topic in ('burrow', 'estop') and value:
                self.walking = False       # the MCU leaves the gait: nothing to refresh
            if topic == 'winch':
                self.publish_winch(float(value))
            elif topic == 'gait':
                self.publish_gait(str(value))
            elif topic == 'estop':
                self.pubs[topic].publish(Bool(data=bool(value)))
            else:
                self.pubs[topic].publish(String(data=str(value)))

    def publish_winch(self, speed: float) -> None:
        """The set-point (m/s) with its evidence deadline (a reel-in only)."""
        valid_until = self.model.reel_in_valid_until() if speed > 0.0 else 0.0
        self.pubs['winch'].publish(winch_command(speed, valid_until, time.monotonic(),
                                                 self.get_clock().now().nanoseconds))

    def publish_gait(self, name: str) -> None:
        """A gait; walking is valid for GAIT_HOLD_S and refreshed by on_timer while the
        operator's last motion key was `w`, so the robot stands if teleop dies."""
        self.walking = name == 'walk'
        self.pubs['gait'].publish(gait_command(name, self.get_clock().now().nanoseconds,
                                               GAIT_HOLD_S))

    def on_tension(self, msg) -> None:
        self.model.tension = msg.wrench.force.x

    def on_joints(self, msg) -> None:
        if WINCH_ROPE_JOINT in msg.name:
            self.model.tether.update(msg.position[msg.name.index(WINCH_ROPE_JOINT)])
        if all(n in msg.name for n in LEG_JOINT_NAMES):
            legs = {k: msg.position[msg.name.index(n)] for k, n in zip(LEG_KEYS, LEG_JOINT_NAMES)}
            axles = axle_angles(legs, LEG_TOLERANCE_RAD)   # left and right must agree
            l1, l2 = ((math.nan, math.nan) if axles.disagreeing
                      else (axles.theta_l1, axles.theta_l2))
            self.model.anchor.legs(l1, l2, time.monotonic())

    def on_estimate(self, msg: AnchorEstimate) -> None:
        m = self.model
        m.status = msg.status
        m.capacity = msg.capacity_n if msg.has_value else math.nan
        m.capacity_lower = msg.capacity_lower_n if msg.has_value else math.nan   # NaN: none
        m.assumed_inputs = frozenset(msg.assumed_inputs)
        m.modelled_inputs = frozenset(msg.modelled_inputs)
        m.capacity_h = msg.h_m
        m.height_measured = 'height' in msg.measured_inputs
        flag = m.anchor.pitch(msg.theta_b_rad, time.monotonic())
        if flag:
            self.get_logger().warning(flag)
            m.message, m.alert = flag, True
        tw = msg.slip_twist
        # The estimate carries the slip direction even while the anchor holds: shown only
        # when the tension exceeds the capacity (predicted motion is zero otherwise).
        m.slip_twist = ((tw.linear.x, tw.linear.z, tw.angular.y) if msg.slipping
                        else (0.0, 0.0, 0.0) if msg.has_value else (math.nan,) * 3)
        # As old as its stamp says: an estimate that sat in a stalled process is not fresh.
        m.t_capacity = sample_time(msg.header.stamp, self.get_clock().now().nanoseconds,
                                   time.monotonic())
        self.send(m.update(time.monotonic()))

    def on_timer(self) -> None:
        m = self.model
        m.unheard = tuple(t for t, p in self.pubs.items() if p.get_subscription_count() == 0)
        self.send(m.update(time.monotonic()))
        if m.winch != 0.0:   # refresh: the MCU's winch deadman stops a winch left unrefreshed
            self.publish_winch(m.winch)
        if self.walking:     # refresh: the bridge stands a walk left unrefreshed
            self.publish_gait('walk')
        header = Header(stamp=self.get_clock().now().to_msg())
        h = m.height()
        self.pub_h.publish(input_value(h.value, h.band, h.provenance, h.source, header))
        self.pub_phi.publish(Float64(data=m.tether.phi(h.value)))


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
        if node.report_dir:
            # The teleop guard: reeling in beyond limit_fraction x lower bound needs the override.
            out = write_tug_series(node.tug_series, node.report_dir, 'teleop', None,
                                   node.model.cfg.limit_fraction,
                                   'teleop session: capacity_node estimates')
            if out:
                print(f'teleop: tug time series {out[1]}')


def main(args=None) -> int:
    if wants_help(args):
        print(usage('teleop', 'rftgls_ros', __doc__,
                    {n: getattr(TeleopConfig(), f) for n, (f, *_) in PARAMETERS.items()}))
        return 0
    term = Terminal()
    return run_node(TeleopNode, 'teleop', tick=term.tick, on_exit=term.close,
                    spin_period_s=0.02, args=args)


if __name__ == '__main__':
    sys.exit(main())
