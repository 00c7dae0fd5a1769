"""capacity_node in process, real rclpy and DDS on loopback: a probe feeds inputs and checks
every output for every status (out_of_range: see test_capacity_map.py)."""
from __future__ import annotations

import math
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from _capacity_common import DH, IN_AIR, PHI, Probe  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from rftgls_core.types import Pull, pull_direction  # noqa: E402
from rftgls_node_base.parameters import ConfigError  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402

# Generous input timeouts: a lock-step test on a loaded machine may take a while between an
# input and the output it waits for (the stale tests set their own).
LIVE = {'map_file': '', 'live_method': 'twist-mesh', 'phi_rad': PHI, 'phi_topic': '/winch/phi',
        **{f'{n}_timeout_s': 5.0 for n in ('joint_states', 'pitch', 'tension', 'height', 'phi')}}


@pytest.fixture
def make(ros_context):
    made = []

    def _make(**params):
        params = {**LIVE, **params}
        node = CapacityNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        ex = SingleThreadedExecutor(context=ros_context)
        probe = Probe(ros_context, ex, expect_phi=bool(params.get('phi_topic')),
                      expect_height=params.get('height_topic', '/winch/height') != '')
        ex.add_node(node)
        ex.add_node(probe.node)
        made.append((ex, node, probe))
        probe.wait_matched()
        return node, probe

    yield _make
    for ex, node, probe in made:
        ex.shutdown()
        node.destroy_node()
        probe.node.destroy_node()


def send(probe, node, state, tension, spread=(0.0, 0.0)):
    """Lock-step: state inputs, wait until the node holds them, then the triggering tension."""
    probe.state(state, spread)
    est = node.estimator
    assert probe.spin_until(lambda: est._inputs.get('height') is not None
                            and (not node.params['phi_topic'] or 'phi' in est._inputs)
                            and est._inputs['height'].value == state.h
                            and 'pitch' in est._inputs
                            and abs(est._inputs['pitch'].value - state.theta_b) < 1e-12
                            and len(est._joints) == 4
                            and est._joints['distal_right'].value
                            == state.theta_l2 - spread[1] / 2)
    m = probe.tension(tension)
    return probe.output_for(m.header.stamp)


def f_along(w, phi=PHI):
    d = pull_direction(phi)
    return w.wrench.force.x * d[0] + w.wrench.force.z * d[1]


def test_ok_and_holding(make, live_predictor):
    node, probe = make()
    cap = send(probe, node, DH, 1.0)
    core = live_predictor.predict(DH, PHI, Pull.BACKWARD)
    assert probe.wait_status('ok')
    assert cap.header.frame_id == 'anchor'
    assert f_along(cap) == pytest.approx(core.capacity_N, rel=1e-9)
    assert cap.wrench.force.y == 0.0 and cap.wrench.torque.y == 0.0
    margin = probe.output_for(cap.header.stamp, 'margin')
    assert f_along(margin) == pytest.approx(core.capacity_N - 1.0, rel=1e-9)
    tw = probe.output_for(cap.header.stamp, 'slip_twist').twist
    assert (tw.linear.x, tw.linear.z, tw.angular.y) == (0.0, 0.0, 0.0)  # holds
    assert probe.spin_until(lambda: probe.last_diag() is not None
                            and probe.last_diag().message == 'ok')
    diag = probe.last_diag()
    assert diag.level == DiagnosticStatus.OK
    values = {kv.key: kv.value for kv in diag.values}
    assert float(values['capacity_N']) == pytest.approx(core.capacity_N, rel=1e-5)


def test_slip_twist_when_tension_exceeds_capacity(make, live_predictor):
    node, probe = make()
    cap = send(probe, node, DH, 40.0)
    core = live_predictor.predict(DH, PHI, Pull.BACKWARD)
    assert f_along(probe.output_for(cap.header.stamp, 'margin')) < 0
    tw = probe.output_for(cap.header.stamp, 'slip_twist').twist
    assert (tw.linear.x, tw.linear.z, tw.angular.y) == pytest.approx(core.slip_twist)
    assert tw.linear.y == 0.0 and tw.angular.x == 0.0


def test_stale_when_an_input_stops(make):
    node, probe = make(pitch_timeout_s=0.15, publish_rate_hz=50.0)
    send(probe, node, DH, 1.0)
    assert probe.wait_status('ok')
    # Only the tension keeps coming: the IMU falls silent, the output turns stale.
    stamp = None
    for _ in range(30):
        stamp = probe.tension(1.0).header.stamp
        probe.spin_until(lambda: False, 0.01)
    cap = probe.output_for(stamp)
    assert probe.wait_status('stale')
    assert all(math.isnan(v) for v in (cap.wrench.force.x, cap.wrench.force.z))
    tw = probe.output_for(stamp, 'slip_twist').twist
    assert math.isnan(tw.linear.x)
    assert probe.wait_diag_level(DiagnosticStatus.STALE)
    assert 'pitch' in {kv.key: kv.value for kv in
                       probe.last_diag().values}['detail']


def test_stale_heartbeat_without_any_input(make):
    node, probe = make(publish_rate_hz=20.0)
    assert probe.spin_until(lambda: len(probe.out['capacity']) >= 2, 3.0)
    assert probe.wait_status('stale')
    assert math.isnan(probe.out['capacity'][-1].wrench.force.x)


def test_invalid_input_nan_joint(make):
    node, probe = make()
    send(probe, node, DH, 1.0)
    probe.joints(math.nan, DH.theta_l2)
    assert probe.spin_until(lambda: math.isnan(node.estimator._joints['proximal_left'].value))
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('invalid_input')
    assert math.isnan(cap.wrench.force.x) and math.isnan(f_along(
        probe.output_for(cap.header.stamp, 'margin')))
    assert probe.wait_diag_level(DiagnosticStatus.ERROR)


def test_invalid_input_imu_without_orientation(make):
    node, probe = make()
    send(probe, node, DH, 1.0)
    probe.imu(DH.theta_b, no_orientation=True)
    assert probe.spin_until(lambda: 'pitch' in node.estimator._malformed)
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('invalid_input') and math.isnan(cap.wrench.force.x)


def test_unsupported_publishes_zero_capacity(make):
    node, probe = make()
    cap = send(probe, node, IN_AIR, 0.5)
    assert probe.wait_status('unsupported')
    assert (cap.wrench.force.x, cap.wrench.force.z) == (0.0, 0.0)
    assert f_along(probe.output_for(cap.header.stamp, 'margin')) == pytest.approx(-0.5)
    tw = probe.output_for(cap.header.stamp, 'slip_twist').twist
    assert math.isnan(tw.linear.x)


def test_leg_disagreement_is_invalid_input(make):
    node, probe = make(leg_tolerance_rad=math.radians(2.0))
    cap = send(probe, node, DH, 1.0, spread=(math.radians(6.0), 0.0))
    assert probe.wait_status('invalid_input') and math.isnan(cap.wrench.force.x)
    assert probe.wait_diag_level(DiagnosticStatus.ERROR)
    assert 'leg_disagreement:joint_states' in probe.last_diag().message


@pytest.mark.parametrize('params, words', [
    ({'tension_timeout_s': -0.1}, 'tension'),
    ({'map_file': '/nonexistent/minirquad.h5'}, 'map file not found|no CapacityMap'),
    ({'pull': 'up'}, 'pull'),
    ({'publish_rate_hz': 0.0}, 'publish_rate_hz'),
    ({'trigger_inputs': ['nonsense']}, 'trigger_inputs'),
])
def test_bad_parameters_raise(ros_context, params, words):
    with pytest.raises(ConfigError, match=words):
        CapacityNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**LIVE, **params}.items()])


# -- bad inputs over real DDS (the full set runs ROS-free in test_capacity_bad_inputs.py) ------
def diag_values(probe):
    return {kv.key: kv.value for kv in probe.last_diag().values}


def test_negative_tension_over_dds_is_invalid(make):
    node, probe = make()
    send(probe, node, DH, 1.0)
    assert probe.wait_status('ok')
    cap = probe.output_for(probe.tension(-5.0).header.stamp)
    assert probe.wait_status('invalid_input') and math.isnan(cap.wrench.force.x)
    assert probe.spin_until(lambda: 'negative_tension:tension' in probe.last_diag().message)


def test_upside_down_imu_over_dds_is_invalid(make):
    node, probe = make()
    send(probe, node, DH, 1.0)
    probe.imu(DH.theta_b, upside_down=True)
    assert probe.spin_until(lambda: 'pitch' in node.estimator._malformed)
    cap = probe.output_for(probe.tension(1.0).header.stamp)
    assert probe.wait_status('invalid_input') and math.isnan(cap.wrench.force.x)
    assert probe.spin_until(lambda: 'implausible_gravity:pitch' in probe.last_diag().message)


def test_stamps_10_s_old_over_dds_are_stale_and_named(make):
    node, probe = make()
    send(probe, node, DH, 1.0)
    cap = probe.output_for(probe.tension(1.0, age_s=10.0).header.stamp)
    assert probe.wait_status('stale') and math.isnan(cap.wrench.force.x)
    assert probe.spin_until(lambda: diag_values(probe)['stale_inputs'] == 'tension')
    assert 'stale_input:tension' in probe.last_diag().message


def test_height_from_the_parameter_is_never_a_plain_ok(make):
    node, probe = make(height_topic='', height_m=DH.h, lower_bound_level=0.0)
    from geometry_msgs.msg import WrenchStamped
    from std_msgs.msg import String
    lowers = []
    probe.node.create_subscription(WrenchStamped, '/capacity_node/capacity_lower',
                                   lowers.append, 10)
    statuses = set()  # every status message, not only the latched last one
    probe.node.create_subscription(String, '/capacity_node/status',
                                   lambda m: statuses.add(m.data), 10)
    est = node.estimator
    probe.state(DH)
    assert probe.spin_until(lambda: 'pitch' in est._inputs and len(est._joints) == 4
                            and 'phi' in est._inputs)
    caps = [probe.output_for(probe.tension(1.0).header.stamp) for _ in range(3)]
    assert probe.wait_status('assumed')
    assert all(math.isfinite(f_along(c)) for c in caps)  # a value, flagged as assumed
    assert probe.wait_diag_level(DiagnosticStatus.WARN)
    assert diag_values(probe)['assumed_inputs'] == 'height'
    assert 'assumed_input:height' in probe.last_diag().message
    # the lower bound over the assumed range is published although the sigma bound is off
    assert probe.spin_until(lambda: any(w.header.stamp == caps[-1].header.stamp
                                        for w in lowers))
    low = next(w for w in lowers if w.header.stamp == caps[-1].header.stamp)
    assert 0.0 <= f_along(low) < f_along(caps[-1])
    assert 'ok' not in statuses and 'ok' not in {m.data for m in probe.out['status']}


@pytest.mark.parametrize('latency_s', [0.0, 0.4])
def test_a_stream_with_400_ms_link_latency_is_never_ok(make, latency_s):
    # Inputs at ~100 Hz, each stamped when it was sampled: latency_s before it is published.
    # The shipped 0.25 s timeouts for the late stream; the on-time control stream gets 2 s so
    # that a loaded test machine cannot make it stale (the 0.25 s boundary itself is tested
    # without ROS in test_capacity_bad_inputs.py).
    timeout_s = 0.25 if latency_s else 2.0
    node, probe = make(**{f'{n}_timeout_s': timeout_s
                          for n in ('joint_states', 'pitch', 'tension')})
    from std_msgs.msg import String
    statuses = []
    probe.node.create_subscription(String, '/capacity_node/status',
                                   lambda m: statuses.append(m.data), 100)
    probe.height(DH.h)
    probe.phi(PHI)
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        probe.joints(DH.theta_l1, DH.theta_l2, stamp=probe.next_stamp(latency_s))
        probe.imu(DH.theta_b, stamp=probe.next_stamp(latency_s))
        probe.tension(1.0, age_s=latency_s)
        probe.spin_until(lambda: False, 0.01)
    probe.spin_until(lambda: False, 0.2)
    if latency_s == 0.0:  # the same stream on time: the node answers ok
        assert 'ok' in statuses, statuses
    else:
        assert statuses and 'ok' not in statuses and 'stale' in statuses, set(statuses)
        assert all(math.isnan(c.wrench.force.x) for c in probe.out['capacity'])


# -- parameters that take effect ---------------------------------------------
def _set_remote(probe, name, value):
    """Set one parameter through capacity_node's parameter service, as `ros2 param set` does."""
    from rcl_interfaces.srv import SetParameters
    client = probe.node.create_client(SetParameters, '/capacity_node/set_parameters')
    assert client.wait_for_service(timeout_sec=5.0)
    fut = client.call_async(SetParameters.Request(
        parameters=[Parameter(name, value=value).to_parameter_msg()]))
    assert probe.spin_until(fut.done)
    probe.node.destroy_client(client)
    return fut.result().results[0]


def test_phi_rad_at_run_time_changes_the_published_capacity(make, live_predictor):
    node, probe = make(phi_topic='')                 # phi comes from the parameter
    cap = send(probe, node, DH, 0.5)
    assert probe.wait_status('assumed')
    before = f_along(cap, PHI)
    assert before == pytest.approx(live_predictor.predict(DH, PHI, 'backward').capacity_N,
                                   rel=1e-9)
    new_phi = 0.0
    res = _set_remote(probe, 'phi_rad', new_phi)
    assert res.successful, res.reason
    assert node.get_parameter('phi_rad').value == new_phi
    cap = send(probe, node, DH, 0.5)
    after = f_along(cap, new_phi)
    # Reference: the core's live model at the new angle (independent of the node).
    assert after == pytest.approx(live_predictor.predict(DH, new_phi, 'backward')
                                  .capacity_N, rel=1e-9)
    assert abs(after - before) > 1e-3


def test_run_time_changes_are_rejected_with_a_reason(make):
    node, probe = make(phi_topic='')
    out_of_range = _set_remote(probe, 'phi_rad', 3.0)                 # beyond +-pi/2
    assert not out_of_range.successful and 'phi_rad' in out_of_range.reason
    start_up_only = _set_remote(probe, 'map_file', '/tmp/other.h5')   # read-only
    assert not start_up_only.successful and 'read-only' in start_up_only.reason
    inconsistent = _set_remote(probe, 'h_min_m', 1.0)                  # above h_max_m
    assert not inconsistent.successful and 'h range' in inconsistent.reason
    assert node.get_parameter('phi_rad').value == PHI                  # nothing applied
    assert node.get_parameter('h_min_m').value == -0.05


def test_topics_are_relative_so_namespaces_apply(ros_context):
    """Inputs and outputs resolve inside the node's namespace (two robots on one domain);
    /diagnostics stays global. Defaults come from the node's own parameters, no overrides."""
    node = CapacityNode(context=ros_context, namespace='robot2', parameter_overrides=[
        Parameter('map_file', value=''), Parameter('live_method', value='twist-mesh')])
    try:
        subs = {name for name, _ in node.get_subscriber_names_and_types_by_node(
            'capacity_node', '/robot2')}
        pubs = {name for name, _ in node.get_publisher_names_and_types_by_node(
            'capacity_node', '/robot2')}
    finally:
        node.destroy_node()
    assert {'/robot2/joint_states', '/robot2/imu/data', '/robot2/winch/tension',
            '/robot2/winch/height'} <= subs
    assert {'/robot2/capacity_node/capacity', '/robot2/capacity_node/status',
            '/diagnostics'} <= pubs


def test_the_live_solvers_answer_before_the_node_subscribes(ros_context):
    """warm_up_solvers (on by default): the shipped map's edge-check solver has answered
    the two warm-up states (a cold and a warm step) when the node is built, so a fresh
    machine compiles it at start-up, not in a tug's first estimate; off: it has answered
    nothing."""
    for warm in (True, False):
        node = CapacityNode(context=ros_context, parameter_overrides=[
            Parameter('warm_up_solvers', value=warm)])
        try:
            steps = node.estimator.predictor.edge.stats().get('steps', 0.0)
            assert steps == (2.0 if warm else 0.0)
            assert (node.warm_up_s is not None) is warm
        finally:
            node.destroy_node()
