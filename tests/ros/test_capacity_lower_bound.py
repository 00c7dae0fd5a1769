"""The conservative lower bound: below the capacity by the propagated 1-sigma uncertainty,
zero when one sigma of state error loses the anchor, and published by the node."""
import math

import pytest

from rftgls_core.maps import CapacityMap, shipped_map_path
from rftgls_core.types import AnchorState
from rftgls_core.uncertainty import capacity_lower_bound

DH = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)


@pytest.fixture(scope='module')
def cmap():
    return CapacityMap.load(shipped_map_path('minirquad'))


def predict(cmap):
    return lambda st, phi: cmap.query(st, phi, 'backward')


def test_medium_sigma_only_gives_the_closed_form(cmap):
    c = cmap.query(DH, 0.0, 'backward').capacity_N
    lower = capacity_lower_bound(predict(cmap), DH, 0.0, c, 0.95, 0.0, 0.0, 0.1)
    # one-sided 95 %: z = 1.6449 (normal table)
    assert lower == pytest.approx(c * (1 - 1.6449 * 0.1), rel=1e-4)


def test_state_sigma_widens_the_band_by_the_finite_difference(cmap):
    c = cmap.query(DH, 0.0, 'backward').capacity_N
    s_h = 0.002
    up = cmap.query(AnchorState(DH.h + s_h, *DH.as_tuple()[1:]), 0.0, 'backward').capacity_N
    dn = cmap.query(AnchorState(DH.h - s_h, *DH.as_tuple()[1:]), 0.0, 'backward').capacity_N
    expect = c - 1.6449 * abs(0.5 * (up - dn))
    got = capacity_lower_bound(predict(cmap), DH, 0.0, c, 0.95, s_h, 0.0, 0.0)
    assert got == pytest.approx(expect, rel=1e-4) and got < c


def test_losing_the_anchor_within_one_sigma_gives_zero(cmap):
    state = AnchorState(0.03, math.radians(5), math.radians(-40), math.radians(30))
    # A 5 cm height error reaches states the map marks unsupported (legs out of the sand).
    assert capacity_lower_bound(predict(cmap), state, 0.0, 5.0, 0.95, 0.05, 0.0, 0.0) == 0.0


def test_node_publishes_the_lower_bound(ros_context, cmap):
    from _capacity_common import PHI, Probe
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from rftgls_core.types import pull_direction
    from rftgls_ros.capacity_node import CapacityNode

    params = {'map_file': str(shipped_map_path('minirquad')), 'phi_rad': PHI,
              'phi_topic': '/winch/phi', 'lower_bound_level': 0.95, 'capacity_rel_sigma': 0.1}
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex, expect_phi=True)
    lowers = []
    probe.node.create_subscription(WrenchStamped, '/capacity_node/capacity_lower',
                                   lowers.append, 10)
    ex.add_node(node)
    ex.add_node(probe.node)
    try:
        probe.wait_matched()
        probe.state(DH)
        assert probe.spin_until(lambda: len(node.estimator._joints) == 4
                                and 'pitch' in node.estimator._inputs
                                and 'phi' in node.estimator._inputs)
        m = probe.tension(1.0)
        cap = probe.output_for(m.header.stamp)
        assert probe.spin_until(lambda: any(w.header.stamp == m.header.stamp for w in lowers))
        low = next(w for w in lowers if w.header.stamp == m.header.stamp)
        d = pull_direction(PHI)
        along = lambda w: w.wrench.force.x * d[0] + w.wrench.force.z * d[1]
        c = cmap.query(DH, PHI, "backward").capacity_N
        expect = capacity_lower_bound(predict(cmap), DH, PHI, c, 0.95, 0.002,
                                      math.radians(1.0), 0.1)
        assert along(cap) == pytest.approx(c, rel=1e-6)
        assert along(low) == pytest.approx(expect, rel=1e-6) and along(low) < along(cap)
    finally:
        ex.shutdown()
        node.destroy_node()
        probe.node.destroy_node()
