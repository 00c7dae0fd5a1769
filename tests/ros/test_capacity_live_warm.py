"""capacity_node's live mode (map_file ''): the default live method is the core's warm-started
direct, which answers as the cold direct does and reports its own time and fallback rate."""
import math

import pytest

from rftgls_core.anchor import AnchorModel
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import minirquad
from rftgls_core.types import AnchorState
from rftgls_ros.capacity.predictor import LIVE_METHODS, make_predictor
from rftgls_ros.capacity_node import PARAMETERS

DH = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)


def test_live_mode_defaults_to_the_warm_solver():
    assert PARAMETERS['live_method'] == 'direct-warm' and 'direct-warm' in LIVE_METHODS


def test_warm_live_predictor_answers_as_cold_direct_and_reports_stats():
    p = make_predictor('', live_method='direct-warm')
    cold = AnchorModel(minirquad(), get_medium('m90_sand'), method='direct')
    phi = math.radians(-20.0)
    for dl in (0.0, 1e-4, 2e-4):
        st = AnchorState(DH.h, DH.theta_b, DH.theta_l1 + dl, DH.theta_l2)
        r, c = p.predict(st, phi, 'backward'), cold.predict(st, phi, 'backward')
        assert r.status is c.status and r.capacity_N == pytest.approx(c.capacity_N, rel=1e-6)
    stats = p.stats()
    assert stats['steps'] == 3 and stats['fallback_rate'] == pytest.approx(1 / 3)
    assert stats['solve_us_median'] > 0 and stats['solve_us_p99'] >= stats['solve_us_median']
