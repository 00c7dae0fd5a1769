"""Shared pieces of the capacity_node tests: reference states and a probe node."""
from __future__ import annotations

import math
import time

from rftgls_core.types import AnchorState

# The DH anchor of the paper's Table II (MiniRQuad): buried, ok status with the live model.
DH = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)
# Same legs with p 0.2 m above the sand: no leg is buried -> unsupported.
IN_AIR = AnchorState.from_degrees(0.20, 5.0, -40.0, 30.0)
PHI = math.radians(-20.0)
NODE_NS = '/capacity_node'
from rftgls_conventions import LEG_JOINT_NAMES as JOINT_NAMES  # noqa: E402


class Probe:
    """A test node that plays the robot (inputs) and the consumer (outputs) of capacity_node."""

    def __init__(self, context, executor=None, name='capacity_probe', expect_phi=False,
                 expect_height=True):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import TwistStamped, WrenchStamped
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Imu, JointState
        from std_msgs.msg import Float64, String
        self.node = rclpy.create_node(name, context=context)
        n = self.node
        self.pub_joints = n.create_publisher(JointState, '/joint_states', 10)
        self.pub_imu = n.create_publisher(Imu, '/imu/data', 10)
        self.pub_tension = n.create_publisher(WrenchStamped, '/winch/tension', 10)
        self.pub_height = n.create_publisher(Float64, '/winch/height', 10)
        self.pub_phi = n.create_publisher(Float64, '/winch/phi', 10)
        self.out = {'capacity': [], 'margin': [], 'slip_twist': [], 'status': [],
                    'diagnostics': []}
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        for key, typ, qos in (('capacity', WrenchStamped, 10), ('margin', WrenchStamped, 10),
                              ('slip_twist', TwistStamped, 10), ('status', String, latched)):
            n.create_subscription(typ, f'{NODE_NS}/{key}',
                                  lambda m, k=key: self.out[k].append(m), qos)
        n.create_subscription(DiagnosticArray, '/diagnostics',
                              lambda m: self.out['diagnostics'].append(m), 10)
        self.executor = executor
        self.expect_phi = expect_phi  # the node under test subscribes to /winch/phi
        self.expect_height = expect_height  # ... and to /winch/height
        self._stamp_ns = 0

    # -- inputs -------------------------------------------------------------------------------
    def next_stamp(self, age_s: float = 0.0):
        """A header stamp: now on the system clock (the node's clock), strictly increasing so
        a stamp identifies the outputs one input produced; or age_s seconds in the past."""
        from builtin_interfaces.msg import Time
        if age_s:  # an old stamp, on purpose
            ns = time.time_ns() - int(age_s * 1e9)
            return Time(sec=ns // 10**9, nanosec=ns % 10**9)
        ns = time.time_ns()
        self._stamp_ns = ns if ns > self._stamp_ns else self._stamp_ns + 1000
        return Time(sec=self._stamp_ns // 10**9, nanosec=self._stamp_ns % 10**9)

    def joints(self, l1, l2, spread=(0.0, 0.0), stamp=None):
        from sensor_msgs.msg import JointState
        m = JointState()
        m.header.stamp = stamp or self.next_stamp()
        m.name = list(JOINT_NAMES)
        m.position = [l1 + spread[0] / 2, l1 - spread[0] / 2, l2 + spread[1] / 2,
                      l2 - spread[1] / 2]
        self.pub_joints.publish(m)
        return m

    def imu(self, theta_b, stamp=None, no_orientation=False, upside_down=False):
        from sensor_msgs.msg import Imu
        m = Imu()
        m.header.stamp = stamp or self.next_stamp()
        m.header.frame_id = 'imu_link'
        beta = -theta_b  # REP-103 pitch is nose-down positive
        m.orientation.y, m.orientation.w = math.sin(beta / 2), math.cos(beta / 2)
        if upside_down:  # then a roll of 180 deg: q_pitch * q_roll(pi) = (w, 0, y, 0) -> ...
            y, w = m.orientation.y, m.orientation.w
            m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = w, 0.0, -y, 0.0
        if no_orientation:
            m.orientation_covariance[0] = -1.0
        m.linear_acceleration_covariance[0] = -1.0  # REP-145: not provided
        self.pub_imu.publish(m)
        return m

    def height(self, h):
        from std_msgs.msg import Float64
        self.pub_height.publish(Float64(data=float(h)))

    def tension(self, t, stamp=None, age_s=0.0):
        from geometry_msgs.msg import WrenchStamped
        m = WrenchStamped()
        m.header.stamp = stamp or self.next_stamp(age_s)
        m.header.frame_id = 'winch_link'
        m.wrench.force.x = float(t)
        self.pub_tension.publish(m)
        return m

    def phi(self, phi):
        from std_msgs.msg import Float64
        self.pub_phi.publish(Float64(data=float(phi)))

    def state(self, state: AnchorState, spread=(0.0, 0.0), phi=PHI):
        self.joints(state.theta_l1, state.theta_l2, spread)
        self.imu(state.theta_b)
        self.height(state.h)
        if phi is not None and self.expect_phi:
            self.phi(phi)

    # -- waiting ------------------------------------------------------------------------------
    def spin_until(self, cond, timeout=5.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return cond()

    def wait_matched(self, timeout=5.0):
        pubs = (self.pub_joints, self.pub_imu, self.pub_tension)
        pubs += (self.pub_height,) if self.expect_height else ()
        pubs += (self.pub_phi,) if self.expect_phi else ()
        assert self.spin_until(lambda: all(p.get_subscription_count() > 0 for p in pubs),
                               timeout), 'capacity_node subscriptions not discovered'

    def output_for(self, stamp, key='capacity', timeout=5.0):
        """The first output message of `key` whose header stamp equals `stamp`."""
        def find():
            for m in self.out[key]:
                if m.header.stamp == stamp:
                    return m
            return None
        assert self.spin_until(lambda: find() is not None, timeout), f'no {key} for {stamp}'
        return find()

    def wait_status(self, word, timeout=3.0):
        """Wait until the latched status topic says `word` (it is published just before the
        values, but on another topic, so it may be processed after them)."""
        return self.spin_until(lambda: self.last_status() == word, timeout)

    def last_diag(self):
        """The capacity_node DiagnosticStatus of the latest /diagnostics message, or None."""
        for arr in reversed(self.out['diagnostics']):
            for st in arr.status:
                if st.name.startswith('capacity_node'):
                    return st
        return None

    def wait_diag_level(self, level, timeout=3.0):
        return self.spin_until(lambda: self.last_diag() is not None
                               and self.last_diag().level == level, timeout)

    def last_status(self):
        return self.out['status'][-1].data if self.out['status'] else None
