"""An input that is not a measurement is never passed off as one: capacity_node in process,
a probe sending the height as rftgls_interfaces/InputValue (value, band, provenance) over real
DDS on loopback, ~/estimate and /diagnostics read back.

Reference for the lower bound: the shipped map queried directly (rftgls_core CapacityMap) at
five heights across the stated band, the scan capacity_node documents for a modelled or
assumed input.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')
pytest.importorskip('rftgls_interfaces')

from _capacity_common import DH, PHI, Probe  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from rftgls_core.maps import CapacityMap, shipped_map_path  # noqa: E402
from rftgls_core.types import AnchorState  # noqa: E402
from rftgls_interfaces.msg import AnchorEstimate, InputValue  # noqa: E402
from rftgls_ros.capacity_node import CapacityNode  # noqa: E402

BAND = 0.002   # m: Table II's spread of h is 1-2 mm (one standard deviation)
PARAMS = {'map_file': 'maps/minirquad_m90_sand.h5', 'phi_topic': '/winch/phi',
          'height_topic': '', 'lower_bound_level': 0.0, 'marker_period_s': 0.0,
          **{f'{n}_timeout_s': 5.0 for n in ('joint_states', 'pitch', 'tension', 'height', 'phi')}}


@pytest.fixture
def stack(ros_context):
    node = CapacityNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in PARAMS.items()])
    ex = SingleThreadedExecutor(context=ros_context)
    probe = Probe(ros_context, ex, expect_phi=True, expect_height=False)
    ex.add_node(node)
    ex.add_node(probe.node)
    probe.wait_matched()
    probe.pub_value = probe.node.create_publisher(InputValue, '/winch/height_estimate', 10)
    probe.estimates = []
    probe.node.create_subscription(AnchorEstimate, '/capacity_node/estimate',
                                   probe.estimates.append, 10)
    assert probe.spin_until(lambda: probe.pub_value.get_subscription_count() > 0
                            and node.count_subscribers('/capacity_node/estimate') > 0)
    yield node, probe
    ex.shutdown()
    node.destroy_node()
    probe.node.destroy_node()


def estimate_for(node, probe, h, provenance, band=BAND) -> AnchorEstimate:
    """Send DH's angles and the height as an InputValue, then the triggering tension; the
    ~/estimate of that tension."""
    probe.joints(DH.theta_l1, DH.theta_l2)
    probe.imu(DH.theta_b)
    probe.phi(PHI)
    msg = InputValue(value=h, band=band, provenance=provenance, source='test')
    msg.header.stamp = probe.next_stamp()
    probe.pub_value.publish(msg)
    est = node.estimator
    t_msg = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9   # the node ages by stamp
    assert probe.spin_until(lambda: 'height' in est._inputs and 'phi' in est._inputs
                            and abs(est._inputs['height'].t - t_msg) < 1e-6
                            and len(est._joints) == 4 and 'pitch' in est._inputs)
    stamp = probe.tension(1.0).header.stamp
    assert probe.spin_until(lambda: any(m.header.stamp == stamp for m in probe.estimates))
    return next(m for m in probe.estimates if m.header.stamp == stamp)


def map_min(h: float, band: float) -> float:
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    return min(cmap.query(AnchorState(float(x), DH.theta_b, DH.theta_l1, DH.theta_l2), PHI,
                          'backward').capacity_N for x in np.linspace(h - band, h + band, 5))


def diag_values(probe) -> dict:
    return {kv.key: kv.value for kv in probe.last_diag().values}


def provenance(est: AnchorEstimate) -> dict[str, str]:
    """Every input's provenance as ~/estimate carries it (three lists, one per word)."""
    out = {n: 'measured' for n in est.measured_inputs}
    out.update({n: 'modelled' for n in est.modelled_inputs})
    out.update({n: 'assumed' for n in est.assumed_inputs})
    return out


INPUTS = ('joint_states', 'pitch', 'tension', 'height', 'phi')


def test_the_status_or_the_provenance_says_when_height_is_not_measured(stack):
    node, probe = stack
    measured = estimate_for(node, probe, DH.h, InputValue.MEASURED)
    assert (measured.status_code, measured.status) == (AnchorEstimate.STATUS_OK, 'ok')
    assert list(measured.assumed_inputs) == list(measured.modelled_inputs) == []
    assert provenance(measured) == dict.fromkeys(INPUTS, 'measured')
    assert math.isnan(measured.capacity_lower_n)          # nothing to cover, no bound asked
    assert probe.spin_until(lambda: probe.last_diag() is not None
                            and diag_values(probe)['provenance'].endswith('height:measured,'
                                                                          'phi:measured'))
    assert probe.last_diag().level == DiagnosticStatus.OK

    # A modelled height with its band (the burrow simulation's, say) gives `ok`, and the
    # provenance says the height is modelled; the lower bound covers the band.
    modelled = estimate_for(node, probe, DH.h, InputValue.MODELLED)
    assert (modelled.status_code, modelled.status) == (AnchorEstimate.STATUS_OK, 'ok')
    assert modelled.has_value and list(modelled.modelled_inputs) == ['height']
    assert not modelled.assumed_inputs
    assert provenance(modelled) == {**dict.fromkeys(INPUTS, 'measured'), 'height': 'modelled'}
    assert 'modelled_input:height' in modelled.reason.split(';')
    assert modelled.capacity_lower_n == pytest.approx(map_min(DH.h, BAND), abs=1e-9)
    assert modelled.capacity_lower_n < modelled.capacity_n
    assert probe.spin_until(lambda: probe.last_diag() is not None
                            and diag_values(probe)['modelled_inputs'] == 'height')
    assert probe.last_diag().message.startswith('ok: ')
    assert 'modelled_input:height' in probe.last_diag().message
    assert 'height:modelled' in diag_values(probe)['provenance']
    assert probe.wait_diag_level(DiagnosticStatus.WARN)

    # A modelled height without a band: the range it may be off by is the node's assumption.
    unbanded = estimate_for(node, probe, DH.h, InputValue.MODELLED, band=math.nan)
    assert (unbanded.status_code, list(unbanded.assumed_inputs)) == (
        AnchorEstimate.STATUS_ASSUMED, ['height'])
    assert provenance(unbanded)['height'] == 'assumed'

    assumed = estimate_for(node, probe, DH.h, InputValue.ASSUMED)
    assert (assumed.status_code, assumed.status) == (AnchorEstimate.STATUS_ASSUMED, 'assumed')
    assert assumed.has_value and list(assumed.assumed_inputs) == ['height']
    assert provenance(assumed) == {**dict.fromkeys(INPUTS, 'measured'), 'height': 'assumed'}
    assert 'assumed_input:height' in assumed.reason.split(';')
    assert assumed.capacity_lower_n == pytest.approx(map_min(DH.h, BAND), abs=1e-9)
    assert probe.spin_until(lambda: diag_values(probe)['assumed_inputs'] == 'height')
    assert probe.wait_diag_level(DiagnosticStatus.WARN)
    assert diag_values(probe)['modelled_inputs'] == ''
    assert 'height:assumed' in diag_values(probe)['provenance']


def test_a_value_without_provenance_or_with_a_bad_band_is_refused(stack):
    node, probe = stack
    unstated = estimate_for(node, probe, DH.h, 0)           # nobody filled the field in
    assert unstated.status_code == AnchorEstimate.STATUS_INVALID_INPUT and not unstated.has_value
    assert 'malformed:height' in unstated.reason.split(';')
    assert math.isnan(unstated.capacity_n)
    bad_band = estimate_for(node, probe, DH.h, InputValue.MODELLED, band=-0.001)
    assert bad_band.status == 'invalid_input' and 'malformed:height' in bad_band.reason
    # A good value brings the estimate back.
    assert estimate_for(node, probe, DH.h, InputValue.MEASURED).status == 'ok'
