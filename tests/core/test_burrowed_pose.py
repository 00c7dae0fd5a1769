"""The modelled burrowed pose (rftgls_core.planning.burrowed): what teleop and behavior_node
send as the burrowed height (provenance modelled) and hold the measured pitch against.

Reference: the pose and sigmas `rftgls plan burrow --json` prints for the paper's modes (the
CLI's own path to the same shipped gait map); the band is two of those sigmas, and the height's
band is widened to cover the paper's measured burrows too (Table II, mean +- SD of six trials:
DH 34 +- 1 mm, DL 36 +- 2 mm, SH 47 +- 2 mm; two SDs)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rftgls_core.cli.main import main as rftgls
from rftgls_core.planning.bound import GaitAnswer
from rftgls_core.planning.burrowed import BAND_SIGMAS, BurrowedPose, burrowed_pose, mode_pose
from rftgls_core.planning.gaits import table_ii_gaits

TABLE_II_H_MM = {'DH': (34.0, 1.0), 'DL': (36.0, 2.0), 'SH': (47.0, 2.0)}


@pytest.mark.parametrize('need, sled', [(1.96, 0.4), (2.94, 0.6)])
def test_a_modes_pose_is_the_planners_prediction_with_bands_covering_the_measurement(
        need, sled, capsys):
    assert rftgls(['plan', 'burrow', '--robot', 'minirquad', '--need-N', str(need), '--phi',
                   '0,-20', '--json']) == 0
    modes = json.loads(capsys.readouterr().out)['modes']
    for name in ('DH', 'DL', 'SH'):
        want = modes[name]['pose']
        got = mode_pose(name, sled)
        assert got is not None and name in got.source and f'{1e3 * sled:.0f} g' in got.source
        # height: the smallest range holding the model's 2-sigma range and Table II's 2 SDs
        mean, sd = (1e-3 * x for x in TABLE_II_H_MM[name])
        lo = min(want['h_m'] - BAND_SIGMAS * want['h_sigma_m'], mean - 2.0 * sd)
        hi = max(want['h_m'] + BAND_SIGMAS * want['h_sigma_m'], mean + 2.0 * sd)
        assert got.h_m - got.h_band_m == pytest.approx(lo, abs=1e-12)
        assert got.h_m + got.h_band_m == pytest.approx(hi, abs=1e-12)
        assert 'Table II' in got.source
        # pitch: the model's own (the IMU checks it after the burrow)
        assert math.degrees(got.theta_b_rad) == pytest.approx(want['theta_b_deg'], abs=1e-9)
        assert math.degrees(got.theta_b_band_rad) == pytest.approx(
            BAND_SIGMAS * want['theta_b_sigma_deg'], abs=1e-9)


def test_a_sled_without_a_gait_map_is_refused_with_the_reason():
    with pytest.raises(ValueError, match='no modelled pose for SH with a 0.5 kg sled: no '
                                         'shipped gait map answers'):
        mode_pose('SH', 0.5)


def test_a_measured_pitch_outside_the_band_is_a_disagreement():
    pose = BurrowedPose(0.040, 0.003, math.radians(3.0), math.radians(1.0), 'test')
    assert pose.pitch_disagreement(math.radians(2.1)) is None          # inside
    assert pose.pitch_disagreement(math.radians(3.9)) is None
    assert pose.pitch_disagreement(math.radians(5.0)) == pytest.approx(math.radians(1.0))
    assert pose.pitch_disagreement(math.radians(-1.0)) == pytest.approx(math.radians(3.0))
    assert pose.pitch_disagreement(math.nan) is None                    # nothing measured
    unbanded = BurrowedPose(0.040, math.nan, math.radians(3.0), math.nan, 'test')
    assert unbanded.pitch_disagreement(math.radians(40.0)) is None      # nothing to hold to


def test_a_gait_without_spread_has_no_band_and_one_without_a_pose_none():
    sh = next(g for g in table_ii_gaits() if g.name == 'SH')
    pose = np.array([0.04, 0.05, -0.7, 0.5])
    failed_spread = GaitAnswer(sh, 'unsupported', 'x', pose, np.full(2, np.nan), None, None,
                               None, [])
    p = burrowed_pose(failed_spread, 'test')
    assert p is not None and p.h_m == 0.04 and math.isnan(p.h_band_m)
    overturned = GaitAnswer(sh, 'degenerate', 'x', np.full(4, np.nan), np.full(2, np.nan),
                            None, None, None, [])
    assert burrowed_pose(overturned, 'test') is None


def test_a_height_band_covering_a_measurement_holds_both_ranges_and_keeps_the_pitch():
    from rftgls_core.robots.measured_burrows import MeasuredBurrow
    model = BurrowedPose(0.040, 0.003, math.radians(3.0), math.radians(1.0), 'model')
    far = MeasuredBurrow(0.047, 0.002, math.radians(2.0), math.radians(0.5), 6, 'lab')
    got = model.covering_height(far)                       # [37, 43] and [43, 51] mm
    assert (got.h_m - got.h_band_m, got.h_m + got.h_band_m) == pytest.approx((0.037, 0.051))
    assert (got.theta_b_rad, got.theta_b_band_rad) == (model.theta_b_rad,
                                                        model.theta_b_band_rad)
    inside = MeasuredBurrow(0.041, 0.0005, 0.0, 0.0, 6, 'lab')
    assert model.covering_height(inside).h_band_m == pytest.approx(0.003)   # already covered
    unbanded = BurrowedPose(0.040, math.nan, 0.0, math.nan, 'model')
    assert unbanded.covering_height(far) is unbanded       # not stated stays not stated
