"""capacity_node's project-typed outputs (rftgls_ros/capacity_msgs.py, capacity_query.py,
marker_publisher.py): the query service, the whole-estimate message and the markers, in process
with a probe, real DDS on loopback.

References come from outside the node: `rftgls capacity --method map --json` (the CLI, a
separate process) for the service, and rftgls_core's CapacityMap.query for the marker geometry.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('rftgls_interfaces')

from _capacity_common import DH, PHI, Probe  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from rftgls_core.maps import CapacityMap, shipped_map_path  # noqa: E402
from rftgls_core.types import AnchorState, pull_direction  # noqa: E402
from rftgls_interfaces.msg import AnchorEstimate  # noqa: E402
from rftgls_interfaces.srv import QueryCapacity  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402

SCALE = 0.02   # m per N, not the default, so a test would see the parameter ignored
PARAMS = {'map_file': 'maps/minirquad_m90_sand.h5', 'phi_rad': PHI, 'marker_period_s': 0.0001,
          'marker_force_scale_m_per_N': SCALE,
          **{f'{n}_timeout_s': 5.0 for n in ('joint_states', 'pitch', 'tension', 'height', 'phi')}}


@pytest.fixture
def stack(ros_context):
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in PARAMS.items()])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex)
    ex.add_node(node)
    ex.add_node(probe.node)
    probe.wait_matched()
    yield node, probe
    ex.shutdown()
    node.destroy_node()
    probe.node.destroy_node()


def cli_capacity(state: AnchorState, phi: float) -> dict:
    deg = [math.degrees(x) for x in (state.theta_b, state.theta_l1, state.theta_l2)]
    out = subprocess.run(
        [sys.executable, '-m', 'rftgls_core.cli.main', 'capacity', '--robot', 'minirquad',
         '--h', repr(state.h), '--theta-b', repr(deg[0]), '--theta-l1', repr(deg[1]),
         '--theta-l2', repr(deg[2]), '--phi', repr(math.degrees(phi)), '--pull', 'backward',
         '--method', 'map', '--json'], capture_output=True, text=True, check=True, timeout=60)
    return json.loads(out.stdout)


def call(probe, req):
    client = probe.node.create_client(QueryCapacity, '/capacity_node/query_capacity')
    assert probe.spin_until(client.service_is_ready, 5.0), 'query service not discovered'
    fut = client.call_async(req)
    assert probe.spin_until(fut.done, 5.0), 'no answer from the query service'
    return fut.result()


@pytest.mark.parametrize('state,phi', [
    (DH, PHI),
    (AnchorState.from_degrees(0.045, 10.0, -20.0, 10.0), math.radians(-5.0)),
])
def test_query_service_matches_cli(stack, state, phi):
    node, probe = stack
    res = call(probe, QueryCapacity.Request(
        h_m=state.h, theta_b_rad=state.theta_b, theta_l1_rad=state.theta_l1,
        theta_l2_rad=state.theta_l2, phi_rad=phi, pull=''))
    ref = cli_capacity(state, phi)
    assert ref['status'] == 'ok' and res.status == 'ok' and res.has_value
    assert res.capacity_n == pytest.approx(ref['capacity_N'], rel=0, abs=1e-9)
    got = (res.slip_twist.linear.x, res.slip_twist.linear.z, res.slip_twist.angular.y)
    assert got == pytest.approx(ref['slip_twist'], abs=1e-9)
    scaled = (res.slip_twist_scaled.linear.x, res.slip_twist_scaled.linear.z,
              res.slip_twist_scaled.angular.y)
    assert scaled == pytest.approx(ref['slip_twist_scaled'], abs=1e-9)


def test_query_service_refuses_bad_requests(stack):
    _node, probe = stack
    off_grid = call(probe, QueryCapacity.Request(h_m=0.2, theta_b_rad=0.0, theta_l1_rad=0.0,
                                                 theta_l2_rad=0.0, phi_rad=PHI))
    assert off_grid.status == 'out_of_range' and not off_grid.has_value
    assert math.isnan(off_grid.capacity_n)
    assert math.isnan(off_grid.capacity_lower_n)
    nan = call(probe, QueryCapacity.Request(h_m=math.nan, phi_rad=PHI))
    assert nan.status == 'invalid_input' and nan.reason == 'not_finite'
    bad_pull = call(probe, QueryCapacity.Request(h_m=DH.h, phi_rad=PHI, pull='sideways'))
    assert bad_pull.status == 'invalid_input' and bad_pull.reason == 'unknown_pull'


def test_estimate_and_markers_match_core(stack):
    node, probe = stack
    got: dict[str, list] = {'estimate': [], 'markers': []}
    probe.node.create_subscription(AnchorEstimate, '/capacity_node/estimate',
                                   got['estimate'].append, 10)
    probe.node.create_subscription(MarkerArray, '/capacity_node/markers',
                                   got['markers'].append, 10)
    assert probe.spin_until(lambda: node.count_subscribers('/capacity_node/markers') > 0)
    tension = 2.5
    probe.state(DH)
    assert probe.spin_until(lambda: len(node.estimator._joints) == 4
                            and 'height' in node.estimator._inputs
                            and 'pitch' in node.estimator._inputs)
    stamp = probe.tension(tension).header.stamp

    def found():
        est = [m for m in got['estimate'] if m.header.stamp == stamp]
        mk = [a for a in got['markers'] if a.markers and a.markers[-1].header.stamp == stamp]
        return (est[0], mk[0]) if est and mk else None

    assert probe.spin_until(lambda: found() is not None), 'no estimate/markers for the input'
    est, arr = found()
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    st = AnchorState(est.h_m, est.theta_b_rad, est.theta_l1_rad, est.theta_l2_rad)
    ref = cmap.query(st, PHI, 'backward')
    # The whole estimate (phi is assumed from its parameter here; the probe sends h).
    assert est.status == 'assumed' and est.has_value
    assert list(est.assumed_inputs) == ['phi']
    assert est.capacity_n == pytest.approx(ref.capacity_N, abs=1e-9)
    assert est.margin_n == pytest.approx(ref.capacity_N - tension, abs=1e-9)
    assert est.tension_n == pytest.approx(tension)
    assert est.method.startswith('map:') and est.pull == 'backward'
    assert est.header.frame_id == 'anchor'
    assert st.theta_b == pytest.approx(DH.theta_b, abs=1e-9)

    markers = {m.ns: m for m in arr.markers if m.action == Marker.ADD}
    assert arr.markers[0].action == Marker.DELETEALL
    assert {'limit_curve', 'tension', 'capacity', 'slip_twist', 'text', 'buried_facets',
            'surface'} <= set(markers)
    assert all(m.header.frame_id == 'winch_link' for m in markers.values())
    c, s = math.cos(st.theta_b), math.sin(st.theta_b)

    def body(fx, fz):   # world (x, z) -> body frame B at p, by the pitch (independent of code)
        return np.array([fx * c + fz * s, 0.0, -fx * s + fz * c])

    d = pull_direction(PHI)
    cap_head = np.array([[p.x, p.y, p.z] for p in markers['capacity'].points])[1]
    np.testing.assert_allclose(cap_head, body(*(SCALE * ref.capacity_N * np.array(d[:2]))),
                               atol=1e-6)
    t_head = np.array([[p.x, p.y, p.z] for p in markers['tension'].points])[1]
    np.testing.assert_allclose(t_head, body(*(SCALE * tension * np.array(d[:2]))), atol=1e-6)
    assert markers['capacity'].color.g > markers['capacity'].color.r   # margin > 30 % of C
    # Limit curve: every sampled tether angle the map answers, C(phi) d(phi) in the body frame.
    pts = np.array([[p.x, p.y, p.z] for p in markers['limit_curve'].points])
    ref_pts = []
    for phi in np.radians(np.arange(-90.0, 90.5, 2.0)):
        r = cmap.query(st, float(phi), 'backward')
        if r.status.has_value:
            dd = pull_direction(float(phi))
            ref_pts.append(body(SCALE * r.capacity_N * dd[0], SCALE * r.capacity_N * dd[1]))
    assert len(ref_pts) >= 10   # the shipped map holds phi -30..10 deg
    np.testing.assert_allclose(pts, np.array(ref_pts), atol=1e-6)
    # The point at the estimate's own phi lies on the curve: the capacity arrow ends on it.
    assert np.min(np.linalg.norm(pts - cap_head, axis=1)) < 1e-6
    tw = ref.slip_twist
    head = np.array([[p.x, p.y, p.z] for p in markers['slip_twist'].points])[1]
    v = np.array(tw[:2]) / np.linalg.norm(tw[:2]) * 0.05
    np.testing.assert_allclose(head, body(*v), atol=1e-6)
    # Buried leg facets: the core's posed robot, centroids below z = 0, relative to p.
    from rftgls_core.robots.presets import get_robot
    cent = get_robot('minirquad').pose(st, 'backward').facets.centroids
    buried = cent[cent[:, 2] < 0.0]
    assert len(buried) > 10
    pts = np.array([[p.x, p.y, p.z] for p in markers['buried_facets'].points])
    want = np.array([body(x, z - st.h) + [0.0, y, 0.0] for x, y, z in buried])
    np.testing.assert_allclose(pts, want, atol=1e-6)
    assert markers['buried_facets'].type == Marker.POINTS
    # The free surface lies h below p.
    surf = np.array([[p.x, p.y, p.z] for p in markers['surface'].points])
    np.testing.assert_allclose(surf[0], body(-0.15, -st.h), atol=1e-9)


def test_behavior_asks_capacity_node(ros_context):
    """behavior_node's mode predictor (ServicePredictor) gets capacity_node's numbers: the same
    as behavior's own local map predictor (same shipped map) for every Table II mode."""
    import threading

    from rftgls_ros.behavior import ANCHOR_MODES
    from rftgls_ros.behavior.model import ModeChooser
    from rftgls_ros.capacity.node_predictor import DEFAULT_MAP, node_predictor
    from rftgls_ros.capacity_query import ServicePredictor
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in PARAMS.items()])
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    spinner = threading.Thread(target=ex.spin, daemon=True)
    spinner.start()
    asker = rclpy.create_node('behavior_node', context=ros_context)
    pred = ServicePredictor(asker, '/capacity_node/query_capacity', timeout_s=5.0)
    try:
        local = node_predictor(DEFAULT_MAP, robot=None, medium=None)
        for name, mode in ANCHOR_MODES.items():
            for phi in (0.0, PHI):
                state = mode.expected_state()
                cap, status = pred(state, phi)
                ref = local.predict(state, phi, 'backward')
                ref_cap, ref_status = (ref.capacity_N if ref.status.has_value else None), ref.status
                assert status == ref_status, name
                assert (cap is None) == (ref_cap is None)
                if cap is not None:
                    assert cap == pytest.approx(ref_cap, abs=1e-9)
        assert pred.calls == 2 * len(ANCHOR_MODES)
        # The lower bound over each mode's height band: capacity_node's own (one question
        # per angle), the same as the chooser computes in this process over the predictor
        # capacity_node builds (the map and its live answers next to the support edge, which
        # SH's band reaches at 51 mm; the node's bound here is its range part alone:
        # lower_bound_level 0).
        like_node = node_predictor(DEFAULT_MAP, robot=None, medium=None,
                                   edge_live_method='direct-warm')
        asked, own = ModeChooser(pred), ModeChooser(like_node)
        for name, mode in ANCHOR_MODES.items():
            for phi in (0.0, PHI):
                state = mode.expected_state()
                got, ref = (c.band_scan(state, phi, mode.h_band) for c in (asked, own))
                assert (got.status, got.gap) == (ref.status, ref.gap), name
                assert got.lower == pytest.approx(ref.lower, abs=1e-9), name
                assert got.point == pytest.approx(ref.point, abs=1e-9), name
                assert got.lower is not None and got.lower <= got.point
        assert pred.calls == 4 * len(ANCHOR_MODES)
    finally:
        pred.destroy()
        asker.destroy_node()
        ex.shutdown()
        spinner.join(5)
        node.destroy_node()


def test_behavior_query_without_capacity_node_is_no_value(ros_context):
    """No service: no value (stale), and the next question does not wait again."""
    import time

    from rftgls_core.types import Status
    from rftgls_ros.capacity_query import ServicePredictor
    asker = rclpy.create_node('lonely_behavior', context=ros_context)
    pred = ServicePredictor(asker, '/nobody/query_capacity', timeout_s=0.3, retry_s=10.0)
    try:
        t0 = time.monotonic()
        assert pred(DH, PHI) == (None, Status.STALE)
        t1 = time.monotonic()
        assert pred(DH, PHI) == (None, Status.STALE)
        assert time.monotonic() - t1 < 0.05 < t1 - t0 + 0.05
    finally:
        pred.destroy()
        asker.destroy_node()


def test_a_stop_request_ends_a_waiting_question_at_once(ros_context):
    """A service that is there but never answers (its node is not spun, as capacity_node's
    at the same SIGINT): a stop request during the wait ends the question within a wait
    slice with no value, not after its timeout, and later questions are not asked at all.
    Without the stop the question would wait its whole 20 s timeout."""
    import threading
    import time

    from rftgls_core.types import Status
    from rftgls_interfaces.srv import QueryCapacity
    from rftgls_ros.capacity_query import WAIT_SLICE_S, ServicePredictor
    server = rclpy.create_node('mute_capacity_node', context=ros_context)
    server.create_service(QueryCapacity, '/mute/query_capacity', lambda req, res: res)
    asker = rclpy.create_node('stopping_behavior', context=ros_context)
    stop = threading.Event()
    pred = ServicePredictor(asker, '/mute/query_capacity', timeout_s=20.0, retry_s=0.0,
                            stopping=stop.is_set)
    try:
        deadline = time.monotonic() + 10.0
        while not pred._client.service_is_ready() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pred._client.service_is_ready()
        threading.Timer(0.5, stop.set).start()
        t0 = time.monotonic()
        r = pred.predict(DH, PHI)
        took = time.monotonic() - t0
        assert (r.status, r.capacity_N, r.reason) == (Status.STALE, None, 'stopping')
        # the stop came 0.5 s in; one slice to see it, the rest scheduling slack
        assert 0.45 <= took <= 0.5 + WAIT_SLICE_S + 1.0, took
        t1 = time.monotonic()
        assert pred.predict(DH, PHI).reason == 'stopping'
        assert time.monotonic() - t1 < WAIT_SLICE_S
        assert pred.calls == 0
    finally:
        pred.destroy()
        asker.destroy_node()
        server.destroy_node()


def test_behavior_node_asks_the_service_unless_configured(ros_context):
    """capacity_source: service (default) -> ServicePredictor; local_map, or the explicit
    own_capacity_fallback, -> its own map; anything else refuses to start."""
    from rftgls_core.predictor.maps import MapPredictor
    from rftgls_ros.behavior_node import BehaviorNode
    from rftgls_ros.capacity_query import ServicePredictor

    def chooser_predictor(**params):
        node = BehaviorNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        try:
            return type(node.machine.chooser.predictor)
        finally:
            node.destroy_node()

    assert chooser_predictor() is ServicePredictor
    assert chooser_predictor(capacity_source='local_map') is MapPredictor
    assert chooser_predictor(own_capacity_fallback=True) is MapPredictor
    with pytest.raises(ValueError, match='capacity_source must be one of service, local_map'):
        chooser_predictor(capacity_source='guess')
    # Its own map may answer for an anchor description (behavior_node takes one):
    # the shipped MiniRQuad description with the shipped map is accepted and answers as the
    # plain map does; the prototype's description is refused against the MiniRQuad map.
    from rftgls_core.description import shipped_description
    mq = str(shipped_description('minirquad'))
    assert chooser_predictor(capacity_source='local_map', anchor_description_file=mq) \
        is MapPredictor
    with pytest.raises(ValueError, match='does not answer for anchor_description_file'):
        chooser_predictor(capacity_source='local_map',
                          anchor_description_file=str(shipped_description('prototype')))
    with pytest.raises(ValueError, match="set them on capacity_node"):
        chooser_predictor(anchor_description_file=mq)       # the service: capacity_node's job
