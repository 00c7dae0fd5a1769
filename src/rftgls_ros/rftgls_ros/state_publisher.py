"""state_publisher: /robot_description, /tf_static and /tf of the robot from its URDF, joint
states and body pose.

robot_state_publisher's job (it has no wheel here), with its topics and its
`robot_description` parameter, plus the body pose a legged anchor has: /robot_description
(std_msgs/String, reliable + transient local: the URDF text, for RViz's RobotModel and
Foxglove); /tf_static (tf2_msgs/TFMessage, transient local) holds the URDF's fixed joints
(imu_link, winch_link); /tf holds the leg joints from /joint_states (the URDF's joints carry
the driver's names, leg_proximal_left ...), and odom -> base_link and odom -> anchor at every
pitch sample (none before the first: the body has no pose yet). With `robot_description`
empty, the URDF of `robot` in minirquad_description (share/minirquad_description/urdf).

ESTIMATED: the body pitch theta_B (from the IMU orientation, or from `pitch_topic`) and the
height h of the winch point p above the free surface (`height_estimate_topic`, an InputValue
such as behavior_node's burrowed height, which says whether it is measured, modelled or
assumed; `height_topic`, a measured Float64; parameter `height_m` until the first sample).
TF has no field for provenance: the drawing is only as good as that input. ASSUMED: p stands at
x = y = 0 of odom (the robot observes no horizontal position), no roll or yaw (the planar
model), odom's z = 0 is the free surface. The math is in rftgls_ros.tf_tree (ROS-free).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, String

from rftgls_conventions import LEG_JOINT_NAMES, quat_xyzw_to_pitch
from rftgls_conventions.safe_read import InputFileError, read_text
from rftgls_interfaces.msg import InputValue
from rftgls_node_base.node_main import run_node, usage, wants_help
from rftgls_node_base.parameters import ConfigError, declare
from tf2_msgs.msg import TFMessage

from .capacity.inputs import (
    IMU_ROLL_LIMIT_RAD,
    IMU_TILT_LIMIT_RAD,
    LEG_LIMIT_RAD,
    frame_problem,
    imu_problem,
)
from .stamps import is_unset
from .tf_tree import (
    Transform,
    UrdfError,
    moving_transforms,
    odom_to_anchor,
    odom_to_base,
    parse_urdf_joints,
    static_transforms,
)

PARAMETERS = {
    'robot_description': ('', 'URDF text; empty = the URDF of `robot` in minirquad_description'),
    'robot': ('minirquad', "URDF of minirquad_description when robot_description is empty: "
              "'minirquad' or 'prototype'"),
    'frame_prefix': ('', 'put in front of every frame name (several robots on one /tf)'),
    'odom_frame': ('odom', 'world frame: x, y of p not observed (0), z = 0 on the free surface'),
    'anchor_frame': ('anchor', "world-aligned frame at p (capacity_node's frame_id); '' = none"),
    'joint_states_topic': ('joint_states', 'sensor_msgs/JointState topic'),
    'imu_topic': ('imu/data', 'sensor_msgs/Imu topic (REP-145; orientation -> body pitch)'),
    'imu_frame_id': ('imu_link', "the IMU messages' header.frame_id (others are dropped)"),
    'pitch_topic': ('', "std_msgs/Float64 body pitch in rad; replaces the IMU if set"),
    'height_topic': ('winch/height', "std_msgs/Float64 measured height of p in m; '' = none"),
    'height_estimate_topic': ('winch/height_estimate', "rftgls_interfaces/InputValue height of "
                              "p in m (measured, modelled or assumed); '' = none"),
    'height_m': (0.03, 'height of p above the free surface until a height sample'),
}


def description_urdf(robot: str) -> str:
    """The URDF text of `robot` in minirquad_description (ConfigError when there is none)."""
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        share = Path(get_package_share_directory('minirquad_description'))
    except PackageNotFoundError:
        raise ConfigError('minirquad_description is not installed (source the workspace) '
                          'and robot_description is empty') from None
    path = share / 'urdf' / f'{robot}.urdf'
    if not path.is_file():
        raise ConfigError(f'robot {robot!r} has no URDF in minirquad_description '
                          f'({path.name})')
    try:
        return read_text(path, 'urdf', 'URDF')
    except InputFileError as exc:
        raise ConfigError(str(exc)) from None


class StatePublisher(Node):
    """Publishes the robot's TF tree; ConfigError from the constructor on a bad URDF."""

    def __init__(self, **kwargs):
        super().__init__('state_publisher', **kwargs)
        p = {}
        for name, (default, text) in PARAMETERS.items():
            lo, hi = (-1.0, 10.0) if name == 'height_m' else (None, None)
            p[name] = declare(self, name, default, text, lo=lo, hi=hi)
        urdf = p['robot_description'] or description_urdf(p['robot'])
        try:
            self.joints = parse_urdf_joints(urdf)
        except UrdfError as exc:
            raise ConfigError(str(exc)) from None
        self.prefix = p['frame_prefix']
        self.odom = self.prefix + p['odom_frame']
        self.base = self.prefix + 'base_link'
        self.anchor = self.prefix + p['anchor_frame'] if p['anchor_frame'] else ''
        self.imu_frame = p['imu_frame_id']
        self.leg_joints = frozenset(LEG_JOINT_NAMES)
        self.height_m = float(p['height_m'])
        self.height_received = False
        self.pitch_rad: float | None = None

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        # /tf and /tf_static are global by ROS convention (tf2 listens there); several robots
        # share them through frame_prefix.
        self.pub_static = self.create_publisher(TFMessage, '/tf_static', latched)
        self.pub_description = self.create_publisher(String, 'robot_description', latched)
        self.pub_description.publish(String(data=urdf))
        self.pub_tf = self.create_publisher(TFMessage, '/tf', 100)
        sensor = qos_profile_sensor_data
        self.create_subscription(JointState, p['joint_states_topic'], self.on_joints, sensor)
        if p['pitch_topic']:
            self.create_subscription(Float64, p['pitch_topic'], self.on_pitch, sensor)
        else:
            self.create_subscription(Imu, p['imu_topic'], self.on_imu, sensor)
        if p['height_topic']:
            self.create_subscription(Float64, p['height_topic'],
                                     lambda m: self.on_height(m.data), sensor)
        if p['height_estimate_topic']:
            self.create_subscription(InputValue, p['height_estimate_topic'],
                                     lambda m: self.on_height(m.value), sensor)
        heights = ' and '.join(t for t in (p['height_topic'], p['height_estimate_topic']) if t)
        self.publish_static()
        self.get_logger().info(
            f'{len(self.joints)} URDF joints, pitch from '
            f'{p["pitch_topic"] or p["imu_topic"]}, height from '
            f'{heights or "parameter height_m"} (assumed {self.height_m} m until a '
            'sample); x, y of p not observed (0)')

    def stamped(self, transforms: list[Transform], stamp) -> TFMessage:
        msg = TFMessage()
        for t in transforms:
            ts = TransformStamped()
            ts.header.stamp = stamp
            ts.header.frame_id = t.parent
            ts.child_frame_id = t.child
            tr, r = ts.transform.translation, ts.transform.rotation
            tr.x, tr.y, tr.z = t.translation
            r.x, r.y, r.z, r.w = t.rotation
            msg.transforms.append(ts)
        return msg

    def now(self):
        return self.get_clock().now().to_msg()

    def publish_static(self) -> None:
        self.pub_static.publish(self.stamped(static_transforms(self.joints, self.prefix),
                                             self.now()))

    def on_joints(self, msg: JointState) -> None:
        # Raw angles are judged before they are drawn: a leg angle beyond LEG_LIMIT_RAD is no
        # reading (docs/design/capacity-inputs.md), and wrapped it would draw a plausible leg.
        names, positions = [], []
        for name, pos in zip(msg.name, msg.position, strict=False):
            if name in self.leg_joints and not abs(pos) <= LEG_LIMIT_RAD:
                continue
            names.append(name)
            positions.append(pos)
        ts = moving_transforms(self.joints, names, positions, self.prefix)
        if ts:
            stamp = msg.header.stamp
            if is_unset(stamp):
                stamp = self.now()
            self.pub_tf.publish(self.stamped(ts, stamp))

    def on_imu(self, msg: Imu) -> None:
        # Judged before the quaternion is normalised: the frame, the norm, roll and gravity
        # (capacity_node's rules); a refused sample draws no pose, the last good one stands.
        if msg.orientation_covariance[0] == -1.0:   # REP-145: no orientation in this IMU
            return
        if frame_problem(msg.header.frame_id, self.imu_frame) is not None:
            return
        o = msg.orientation
        q = (o.x, o.y, o.z, o.w)
        a = msg.linear_acceleration
        accel = None if msg.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
        if imu_problem(q, accel, IMU_TILT_LIMIT_RAD, IMU_ROLL_LIMIT_RAD) is not None:
            return
        self.pitch_rad = quat_xyzw_to_pitch(*q)
        self.publish_pose(msg.header.stamp)

    def on_pitch(self, msg: Float64) -> None:
        if abs(msg.data) <= math.pi / 2:    # a pitch (not NaN, not beyond vertical)
            self.pitch_rad = float(msg.data)
            self.publish_pose(None)

    def on_height(self, h: float) -> None:
        if h == h:     # not NaN
            self.height_m = float(h)
            self.height_received = True

    def publish_pose(self, stamp) -> None:
        # Only with a measured pitch: before the first sample the body has no pose in odom
        # (a level body drawn from nothing would look like a measurement).
        if self.pitch_rad is None:
            return
        if stamp is None or is_unset(stamp):
            stamp = self.now()
        ts = [odom_to_base(self.height_m, self.pitch_rad, self.odom, self.base)]
        if self.anchor:
            ts.append(odom_to_anchor(self.height_m, self.odom, self.anchor))
        self.pub_tf.publish(self.stamped(ts, stamp))


def main(args=None) -> int:
    if wants_help(args):
        print(usage('state_publisher', 'rftgls_ros', __doc__,
                    {n: d for n, (d, _t) in PARAMETERS.items()}))
        return 0
    return run_node(StatePublisher, 'state_publisher', config_errors=(ConfigError,),
                    args=args)


if __name__ == '__main__':
    sys.exit(main())
