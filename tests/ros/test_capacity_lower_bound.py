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

        # One bound: asked about the same state (~/query_capacity, what behavior_node chooses
        # and checks on), the node answers the bound it published. The message carries
        # lower x d(phi) and `along` projects it back onto the unit d: a few ulps apart.
        from rftgls_interfaces.srv import QueryCapacity
        client = probe.node.create_client(QueryCapacity, '/capacity_node/query_capacity')
        assert probe.spin_until(client.service_is_ready)

        def ask(h_band):
            fut = client.call_async(QueryCapacity.Request(
                h_m=DH.h, theta_b_rad=DH.theta_b, theta_l1_rad=DH.theta_l1,
                theta_l2_rad=DH.theta_l2, phi_rad=PHI, h_band_m=h_band))
            assert probe.spin_until(fut.done), 'no answer from the query service'
            return fut.result()

        exact = ask(0.0)
        assert exact.capacity_n == c and exact.capacity_lower_n == pytest.approx(
            along(low), rel=1e-12)
        # With h known only within +- 3 mm, the range part joins: the smallest capacity of
        # the map at the five heights range_bound scans (h, +-1.5 mm, +-3 mm), if smaller.
        band = ask(0.003)
        hs = [DH.h + f * 0.003 for f in (-1.0, -0.5, 0.0, 0.5, 1.0)]
        scan = min(cmap.query(AnchorState(h, *DH.as_tuple()[1:]), PHI, 'backward').capacity_N
                   for h in hs)
        assert band.capacity_lower_n == min(expect, scan) <= exact.capacity_lower_n
        refused = ask(-0.001)
        assert refused.status == 'invalid_input' and refused.reason == 'bad_h_band'
        assert math.isnan(refused.capacity_lower_n)
    finally:
        ex.shutdown()
        node.destroy_node()
        probe.node.destroy_node()


# -- the bound on a grid of tether angles (capacity/lower_bound.py) -------------------------
STEP = math.radians(0.5)
SETTINGS = dict(level=0.95, h_sigma_m=0.002, theta_b_sigma_rad=math.radians(1.0),
                capacity_rel_sigma=0.05, h_range_m=(-0.05, 0.30), phi_limit_rad=math.pi / 2)
MODELLED_H = (('height', 0.0029),)   # a modelled height with its band, as behavior sends it


def counted(cmap):
    calls = []

    def f(st, phi):
        calls.append((st, phi))
        return cmap.query(st, phi, 'backward')
    return f, calls


def test_the_grid_bound_is_the_smaller_exact_bound_of_the_two_bracketing_angles(cmap):
    """The bound at phi on the 0.5 deg grid equals, to the last bit, the smaller of the
    exact-phi bounds at the grid angles on either side (the same predictor calls), and so
    lies at or below the exact bound wherever the capacity is monotone in phi over a step."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    grid = LowerBound(predict(cmap), BoundSettings(**SETTINGS, phi_step_rad=STEP))
    exact = LowerBound(predict(cmap), BoundSettings(**SETTINGS))
    below = 0
    for phi in (-0.3, -0.2051, -0.1, -0.0541, 0.0123):
        i = math.floor(phi / STEP)       # grid angles are i x step (lower_bound._angle)
        ends = [exact.bound(DH, p, cmap.query(DH, p, 'backward'), MODELLED_H)
                for p in (i * STEP, (i + 1) * STEP)]
        got = grid.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
        assert got == min(ends)
        below += got <= exact.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
    assert below == 5


def test_a_creeping_phi_asks_the_predictor_again_only_when_it_leaves_its_bracket(cmap):
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    f, calls = counted(cmap)
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP))
    first = bound.bound(DH, -0.0541, cmap.query(DH, -0.0541, 'backward'), MODELLED_H)
    n = len(calls)
    assert n > 0
    # 0.01 deg per tension sample, as the sled's approach turns the tether: the same bracket
    phis = [-0.0541 - math.radians(0.01) * k for k in range(1, 20)]
    assert all(math.floor(p / STEP) == math.floor(-0.0541 / STEP) for p in phis)
    assert all(bound.bound(DH, p, cmap.query(DH, p, 'backward'), MODELLED_H) == first
               for p in phis)
    assert len(calls) == n
    # the next bracket shares one end: only its new end is solved
    nxt = (math.floor(-0.0541 / STEP) - 0.5) * STEP
    bound.bound(DH, nxt, cmap.query(DH, nxt, 'backward'), MODELLED_H)
    assert 0 < len(calls) - n < n


def test_a_bracket_end_without_a_value_makes_the_grid_bound_zero(cmap):
    """A predictor that holds nothing from phi -0.055 rad up: at phi -0.0541 the upper grid
    end (-3.0 deg) cannot hold, so the bound is 0, never the lower end's value."""
    from rftgls_core.surfaces.base import CapacityResult
    from rftgls_core.types import Status
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound

    def f(st, phi):
        if phi > -0.055:
            return CapacityResult(phi=phi, status=Status.UNSUPPORTED, method='test')
        return cmap.query(st, phi, 'backward')
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP))
    phi = -0.0541   # bracket [-3.5, -3.0] deg = [-0.0611, -0.0524] rad
    assert bound.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H) == 0.0


def test_prefetch_prepares_the_neighbouring_brackets_one_prediction_at_a_time(cmap):
    """After a bound at phi, each prefetch call makes exactly one prediction, until both
    neighbouring grid angles are known (False); the creeping phi then enters the next bracket
    with no prediction at all, and its bound is the one a bound without prefetch gives."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    f, calls = counted(cmap)
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP))
    phi = -0.0541
    bound.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
    n, steps, last = len(calls), 0, len(calls)
    while bound.prefetch():
        steps += 1
        assert len(calls) - last in (0, 1)   # one prediction, or a bound finished without
        last = len(calls)
        assert steps < 100
    made = len(calls) - n
    assert made >= 2 and steps == made + 2   # the two grid angles each finish once
    below = (math.floor(phi / STEP) - 0.5) * STEP      # inside the bracket below
    above = (math.floor(phi / STEP) + 1.5) * STEP      # inside the bracket above
    for p in (below, above):
        before = len(calls)
        got = bound.bound(DH, p, cmap.query(DH, p, 'backward'), MODELLED_H)
        assert len(calls) == before
        fresh = LowerBound(predict(cmap), BoundSettings(**SETTINGS, phi_step_rad=STEP))
        assert got == fresh.bound(DH, p, cmap.query(DH, p, 'backward'), MODELLED_H)


def test_prefetch_prepares_the_bracket_the_phi_enters_at_every_grid_angle(cmap):
    """At every grid angle of a tug's range (-20 to 20 deg), a prefetched neighbour is found
    when phi gets there: angles are formed one way (index x step), so a neighbour reached
    as angle + step is the same number, not one an ulp off under another key."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    f, calls = counted(cmap)
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP))
    missed = []
    for i in range(-40, 40):
        phi = (i + 0.5) * STEP
        bound.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
        while bound.prefetch():
            pass
        for p in ((i - 0.5) * STEP, (i + 1.5) * STEP):   # inside the brackets either side
            before = len(calls)
            bound.bound(DH, p, cmap.query(DH, p, 'backward'), MODELLED_H)
            if len(calls) != before:
                missed.append((i, round(math.degrees(p), 2)))
    assert not missed, missed


def test_prefetch_prepares_the_side_phi_moved_to_first(cmap):
    """A tug's phi creeps one way: after it moved down (then up), the first predictions of
    prefetch all go to the grid angle below (above) the bracket."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    i = math.floor(-0.0541 / STEP)
    for direction, side in ((-1, i * STEP - STEP), (+1, (i + 2) * STEP)):
        f, calls = counted(cmap)
        bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP))
        for phi in (-0.0541 - direction * 1e-4, -0.0541):
            bound.bound(DH, phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
        n = len(calls)
        for _ in range(5):
            bound.prefetch()
        assert {p for _, p in calls[n:]} == {side}, (direction, calls[n:])


def _tug_course(n_left: float = 0.15):
    """(theta_B, phi) rad per tension sample of the demo's 400 g tug: 0.754 m of tether
    reeled at 0.5 mm per sample (50 mm/s at 100 Hz) to 0.15 m, phi following the taut tether
    at h 44 mm (rftgls_ros.tether: -2.6 deg at the start, -13 deg at the end, ten times
    faster there), the pitch creeping 0.001 deg per sample from 10.3 deg (the physics body
    under pre-tension)."""
    from rftgls_ros.tether import TetherTracker
    tether = TetherTracker(rope_length=0.754)
    course = []
    for k in range(int((0.754 - n_left) / 5e-4)):
        tether.update(k * 5e-4)
        course.append((math.radians(10.3 + 0.001 * k), tether.phi(0.044)))
    return course


def test_prefetch_keeps_up_with_the_end_of_a_tug(cmap):
    """With one prefetch call after each bound (as capacity_node makes them: one prediction per
    tension sample), no bound of the demo's 400 g tug after its first ten (the first cells,
    which nothing before them prepared) waits for a prediction: prefetch prepares the
    corners ahead, earliest needed first, and skips the corners the course leaves before it
    needs them. Preparing only the cells next to the current one, 14 of those bounds waited,
    six of them on 9 to 18 predictions (next to the support edge each is a live solve of
    20-28 ms): near the end phi enters a new cell every ten samples while the pitch enters
    new rows."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    f, calls = counted(cmap)
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP,
                                        theta_b_step_rad=PITCH_STEP))
    waited = []
    for k, (tb, phi) in enumerate(_tug_course()):
        st = AnchorState(0.044, tb, math.radians(-20.0), math.radians(-20.0))
        before = len(calls)
        bound.bound(st, phi, None, MODELLED_H)
        if k >= 10 and len(calls) > before:
            waited.append((k, len(calls) - before))
        bound.prefetch()
    assert not waited, waited


def test_prefetch_ahead_gives_the_bounds_a_bound_without_prefetch_gives(cmap):
    """Prefetching changes when a corner is predicted, never the bound: along the tug's
    course every bound equals, to the last bit, that of a LowerBound that never prefetches
    (the map's answers do not depend on their order)."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    settings = BoundSettings(**SETTINGS, phi_step_rad=STEP, theta_b_step_rad=PITCH_STEP)
    ahead, plain = LowerBound(predict(cmap), settings), LowerBound(predict(cmap), settings)
    for tb, phi in _tug_course()[::7]:
        st = AnchorState(0.044, tb, math.radians(-20.0), math.radians(-20.0))
        got = ahead.bound(st, phi, None, MODELLED_H)
        for _ in range(7):
            ahead.prefetch()
        assert got == plain.bound(st, phi, None, MODELLED_H)


def test_a_value_is_a_corner_from_one_step_before_until_one_step_after():
    """_ahead's spans: values ahead enter when x comes within a step and leave a step past;
    the bracket's values are in use now; an axis that does not move has no value ahead."""
    from rftgls_ros.capacity.lower_bound import _ahead
    step = 0.5
    got = _ahead(0.1, step, 0.01, math.inf, 3, 1e9)
    assert [v for v, _, _ in got] == [0.0, 0.5, 1.0, 1.5, 2.0]
    enter = {v: e for v, e, _ in got}
    leave = {v: lv for v, _, lv in got}
    assert enter[0.0] == enter[0.5] == 0.0
    assert leave[0.0] == pytest.approx(40.0) and leave[0.5] == pytest.approx(90.0)
    assert enter[1.0] == pytest.approx(40.0) and leave[1.0] == pytest.approx(140.0)
    assert enter[2.0] == pytest.approx(140.0)
    down = _ahead(0.1, step, -0.01, math.inf, 2, 1e9)
    assert [v for v, _, _ in down] == [0.0, 0.5, -0.5, -1.0]
    assert {v: e for v, e, _ in down}[-0.5] == pytest.approx(10.0)
    assert {v: lv for v, _, lv in down}[0.5] == pytest.approx(10.0)
    assert _ahead(0.1, step, 0.0, math.inf, 3, 1e9) == [(0.0, 0.0, math.inf),
                                                        (0.5, 0.0, math.inf)]
    assert [v for v, _, _ in _ahead(0.1, step, 0.01, 1.2, 5, 1e9)] == [0.0, 0.5, 1.0]
    assert [v for v, _, _ in _ahead(0.1, step, 0.01, math.inf, 5, 100.0)] == [0.0, 0.5, 1.0, 1.5]


def test_prefetch_does_nothing_at_the_exact_phi():
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    bound = LowerBound(lambda st, ph: pytest.fail('no prediction expected'),
                       BoundSettings(**SETTINGS))
    assert bound.prefetch() is False


# -- ... and of body pitches ----------------------------------------------------------------
PITCH_STEP = math.radians(0.1)


def _pitched(theta_b_deg: float) -> AnchorState:
    return AnchorState(DH.h, math.radians(theta_b_deg), DH.theta_l1, DH.theta_l2)


def test_the_pitch_grid_bound_is_the_smallest_exact_bound_at_the_cells_corners(cmap):
    """With both grids the bound at (theta_B, phi) equals, to the last bit, the smallest of
    the exact bounds at the four corners of its grid cell (grid values formed as i x step)."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    grid = LowerBound(predict(cmap), BoundSettings(**SETTINGS, phi_step_rad=STEP,
                                                   theta_b_step_rad=PITCH_STEP))
    exact = LowerBound(predict(cmap), BoundSettings(**SETTINGS))
    on_node = 0
    for tb_deg, phi in ((5.0371, -0.0541), (4.9512, -0.2051), (5.3, 0.0123)):
        st = _pitched(tb_deg)
        i, j = math.floor(st.theta_b / PITCH_STEP), math.floor(phi / STEP)
        # a value on a node is its own bracket (5.3 deg is 53 x 0.1 deg to the last bit)
        pitches = [i] if i * PITCH_STEP == st.theta_b else [i, i + 1]
        corners = []
        for a in pitches:
            c = AnchorState(st.h, a * PITCH_STEP, st.theta_l1, st.theta_l2)
            corners += [exact.bound(c, b * STEP, cmap.query(c, b * STEP, 'backward'), MODELLED_H)
                        for b in (j, j + 1)]
        on_node += len(pitches) == 1
        got = grid.bound(st, phi, cmap.query(st, phi, 'backward'), MODELLED_H)
        assert got == min(corners)
    assert on_node == 1


def test_a_creeping_pitch_asks_the_predictor_again_only_when_it_leaves_its_cell(cmap):
    """The physics body's anchor under pre-tension turned by 0.001 deg per estimate: inside
    one 0.1 deg cell no prediction at all; with prefetch done, the next cell neither."""
    from rftgls_ros.capacity.lower_bound import BoundSettings, LowerBound
    f, calls = counted(cmap)
    bound = LowerBound(f, BoundSettings(**SETTINGS, phi_step_rad=STEP,
                                        theta_b_step_rad=PITCH_STEP))
    phi = -0.0541
    first = bound.bound(_pitched(5.0391), phi, cmap.query(DH, phi, 'backward'), MODELLED_H)
    n = len(calls)
    assert n > 0
    for k in range(1, 30):              # 5.0391 deg down to 5.0101 deg: the same cell
        st = _pitched(5.0391 - 0.001 * k)
        assert bound.bound(st, phi, cmap.query(st, phi, 'backward'), MODELLED_H) == first
    assert len(calls) == n
    steps = 0
    while bound.prefetch():
        steps += 1
        assert steps < 400
    assert len(calls) > n               # the neighbouring cells were prepared ...
    for tb in (4.95, 5.15):             # ... below and above in pitch
        before = len(calls)
        st = _pitched(tb)
        got = bound.bound(st, phi, cmap.query(st, phi, 'backward'), MODELLED_H)
        assert len(calls) == before, tb
        fresh = LowerBound(predict(cmap), BoundSettings(**SETTINGS, phi_step_rad=STEP,
                                                        theta_b_step_rad=PITCH_STEP))
        assert got == fresh.bound(st, phi, cmap.query(st, phi, 'backward'), MODELLED_H)


def test_a_negative_pitch_step_is_refused():
    from rftgls_node_base.parameters import ConfigError
    from rftgls_ros.capacity.estimator import EstimatorConfig
    with pytest.raises(ConfigError, match='lower_bound_theta_b_step_rad'):
        EstimatorConfig(lower_bound_theta_b_step_rad=-1e-3).check()
