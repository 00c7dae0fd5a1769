"""behavior_node's wiring, in process over real DDS on loopback: what it reads of capacity_node
(its whole estimate, nothing else), how an estimate becomes what the machine judges, and how
the height it assumes goes out (marked assumed, never as a measurement)."""
from __future__ import annotations

import math
import time

import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('rftgls_interfaces')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402

from rftgls_interfaces.msg import AnchorEstimate, InputValue  # noqa: E402
from rftgls_ros.behavior import evidence  # noqa: E402
from rftgls_ros.behavior_node import BehaviorNode  # noqa: E402


@pytest.fixture
def rig(ros_context):
    made = []

    def make(**params):
        node = BehaviorNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        probe = rclpy.create_node('behavior_probe', context=ros_context)
        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(node)
        ex.add_node(probe)
        made.append((ex, node, probe))
        return node, probe, ex

    yield make
    for ex, node, probe in made:
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()


def spin_until(ex, cond, timeout=5.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end and not cond():
        ex.spin_once(timeout_sec=0.02)
    return cond()


def subscriptions(probe, node_name):
    """{topic: [types]} the ROS graph lists for a node's subscriptions (discovery over DDS)."""
    return dict(probe.get_subscriber_names_and_types_by_node(node_name, '/'))


def test_reads_only_the_estimate_of_capacity_node_and_no_diagnostics(rig):
    _node, probe, ex = rig()
    assert spin_until(ex, lambda: '/joint_states' in subscriptions(probe, 'behavior_node'))
    subs = subscriptions(probe, 'behavior_node')
    assert {t for t in subs if t.startswith('/capacity_node/')} == {'/capacity_node/estimate'}
    assert subs['/capacity_node/estimate'] == ['rftgls_interfaces/msg/AnchorEstimate']
    assert '/diagnostics' not in subs, subs
    # The robot's own inputs, for comparison: the rest of what it reads.
    assert set(subs) == {'/capacity_node/estimate', '/joint_states', '/imu', '/winch/tension',
                         '/energy', '/minirquad/link'}, subs
    # Its private node for capacity_node's query service is a client only.
    assert subscriptions(probe, 'behavior_node_capacity_query') == {}


def test_one_estimate_message_is_what_the_machine_judges(rig):
    node, probe, ex = rig(accept_assumed_inputs='height')
    pub = probe.create_publisher(AnchorEstimate, '/capacity_node/estimate', 10)
    assert spin_until(ex, lambda: pub.get_subscription_count() > 0)

    def send(**fields):
        t0 = node.obs.t_capacity
        # computed at the height behavior_node sends, unless a test says otherwise
        fields.setdefault('h_m', node.machine.height)
        msg = AnchorEstimate(has_value=True, capacity_n=2.5, capacity_lower_n=1.3, **fields)
        msg.slip_twist.linear.x, msg.slip_twist.linear.z, msg.slip_twist.angular.y = \
            0.6, -0.2, 0.77
        pub.publish(msg)
        assert spin_until(ex, lambda: node.obs.t_capacity > t0)
        return node.obs

    obs = send(status_code=AnchorEstimate.STATUS_ASSUMED, status='assumed',
               assumed_inputs=['height'])
    assert (obs.capacity, obs.capacity_status, obs.assumed_inputs) == \
        (2.5, 'assumed', frozenset({'height'}))
    assert obs.slip_twist == (0.0, 0.0, 0.0)       # holds: the predicted motion is zero
    assert node.machine.evidence().usable            # an accepted assumed input
    obs = send(status_code=AnchorEstimate.STATUS_ASSUMED, status='assumed',
               assumed_inputs=['height', 'phi'], slipping=True)
    assert obs.slip_twist == (0.6, -0.2, 0.77)
    assert node.machine.evidence().reason == evidence.ASSUMED_NOT_ACCEPTED
    # The code decides, not the deprecated word; a code nobody filled in is no value.
    obs = send(status_code=0, status='ok')
    assert obs.capacity_status == 'unknown_0'
    assert node.machine.evidence().reason == 'status_unknown_0'
    obs = send(status_code=AnchorEstimate.STATUS_OK, status='ok')
    assert obs.capacity_status == 'ok' and obs.assumed_inputs == frozenset()
    assert node.machine.evidence().usable
    # Each estimate is one sample of the tug series, with its lower bound.
    assert [s.capacity_lower_n for s in node.tug_series.samples][-4:] == [1.3] * 4
    # An ok on a modelled input (its band covered) is evidence, decided on its lower bound
    # (1.3 N, not the 2.5 N point estimate); without a lower bound it is not evidence.
    obs = send(status_code=AnchorEstimate.STATUS_OK, status='ok', modelled_inputs=['height'])
    assert obs.capacity_status == 'ok' and node.machine.evidence().usable
    assert node.machine.decision_capacity() == pytest.approx(1.3)
    # An estimate at another height than the one sent answers an old question (the new
    # height's estimate is still on its way): not evidence, until capacity_node catches up.
    # A height capacity_node measures itself is not behavior_node's to check.
    h = node.machine.height
    send(status_code=AnchorEstimate.STATUS_OK, status='ok', h_m=h + 3e-4)
    v = node.machine.evidence()
    assert (v.usable, v.reason, v.transient) == (False, evidence.OTHER_HEIGHT, True)
    send(status_code=AnchorEstimate.STATUS_OK, status='ok', h_m=h + 3e-4,
         measured_inputs=['height'])
    assert node.machine.evidence().usable
    t0 = node.obs.t_capacity
    pub.publish(AnchorEstimate(status_code=AnchorEstimate.STATUS_OK, has_value=True,
                               capacity_n=2.5, capacity_lower_n=float('nan'),
                               modelled_inputs=['height'], h_m=h))
    assert spin_until(ex, lambda: node.obs.t_capacity > t0)
    assert node.machine.evidence().reason == evidence.NO_LOWER_BOUND


def test_burrow_modes_planned_without_a_gait_map_for_the_sled_is_refused_in_one_line(spawn):
    """The gait maps are per sled: a sled without one is refused at start, one line."""
    import subprocess
    proc = spawn(['ros2', 'run', 'rftgls_ros', 'behavior_node', '--ros-args', '-p',
                  'burrow_modes:=planned', '-p', 'sled_mass_kg:=0.5'], stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, (out, err)
    assert err.strip().startswith("behavior_node: error: burrow_modes 'planned': no gait map "
                                  "for a 500 g sled"), err
    assert len(err.strip().splitlines()) == 1, err


def test_the_height_it_sends_is_marked_assumed(rig):
    node, probe, ex = rig(h_walk_m=0.055)
    got = []
    # best-effort, as behavior_node publishes it (and capacity_node reads it)
    probe.create_subscription(InputValue, '/winch/height_estimate', got.append,
                              qos_profile_sensor_data)
    assert spin_until(ex, lambda: len(got) >= 3)
    m = got[-1]
    assert (m.value, m.provenance) == (0.055, InputValue.ASSUMED)
    assert math.isnan(m.band) and 'not measured' in m.source
    assert m.header.stamp.sec > 0
    # No plain Float64 height: capacity_node would take it for a measurement.
    assert '/winch/height' not in {p.topic_name for p in node.publishers}
    assert probe.count_publishers('/winch/height') == 0


def test_freshness_is_the_age_of_the_sample_not_of_its_receipt(rig):
    node, probe, ex = rig(accept_assumed_inputs='height')
    pub = probe.create_publisher(AnchorEstimate, '/capacity_node/estimate', 10)
    ten = probe.create_publisher(WrenchStamped, '/winch/tension', qos_profile_sensor_data)
    assert spin_until(ex, lambda: pub.get_subscription_count() > 0
                      and ten.get_subscription_count() > 0)

    def stamp(age_s: float):
        return (probe.get_clock().now() - Duration(nanoseconds=int(age_s * 1e9))).to_msg()

    def send(age_s: float):
        n = len(node.tug_series.samples)
        msg = AnchorEstimate(status_code=AnchorEstimate.STATUS_OK, status='ok',
                             has_value=True, capacity_n=2.5, capacity_lower_n=2.0,
                             h_m=node.machine.height)
        msg.header.stamp = stamp(age_s)
        pub.publish(msg)
        assert spin_until(ex, lambda: len(node.tug_series.samples) > n)
        return node.machine.evidence()

    # Just received, but its sample is 0.3 s old (a slow link): not evidence.
    v = send(0.3)
    assert (v.usable, v.reason) == (False, evidence.TIMEOUT), v
    assert 290 <= float(v.detail.split(' ms')[0].split()[-1]) < 400, v.detail
    assert send(0.0).usable
    # A heartbeat estimate (stamped now) over a link whose last tension sample is 0.2 s old
    # is as old as that sample: every estimate is built on it.
    w = WrenchStamped()
    w.header.stamp = stamp(0.2)
    w.wrench.force.x = 1.0
    ten.publish(w)
    assert spin_until(ex, lambda: node.obs.tension == 1.0)
    v = send(0.0)
    assert (v.usable, v.reason) == (False, evidence.TIMEOUT), v
    w.header.stamp = stamp(0.0)
    ten.publish(w)
    assert spin_until(ex, lambda: node.now_s() - node.obs.t_tension < 0.1)
    assert send(0.0).usable
