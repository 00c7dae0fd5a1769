"""The modelled burrowed pose (rftgls_core.planning.burrowed): what teleop and behavior_node
send as the burrowed height (provenance modelled) and hold the measured pitch against.

Reference: the pose and sigmas `rftgls plan burrow --json` prints for the paper's modes (the
CLI's own path to the same shipped gait map); the band is two of those sigmas."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rftgls_core.cli.main import main as rftgls
from rftgls_core.planning.bound import GaitAnswer
from rftgls_core.planning.burrowed import BAND_SIGMAS, BurrowedPose, burrowed_pose, mode_pose
from rftgls_core.planning.gaits import table_ii_gaits


@pytest.mark.parametrize('need, sled', [(1.96, 0.4), (2.94, 0.6)])
def test_a_modes_pose_is_the_planners_prediction_with_two_sigma_bands(need, sled, capsys):
    assert rftgls(['plan', 'burrow', '--robot', 'minirquad', '--need-N', str(need), '--phi',
                   '0,-20', '--json']) == 0
    modes = json.loads(capsys.readouterr().out)['modes']
    for name in ('DH', 'DL', 'SH'):
        want = modes[name]['pose']
        got = mode_pose(name, sled)
        assert got is not None and name in got.source and f'{1e3 * sled:.0f} g' in got.source
        assert got.h_m == pytest.approx(want['h_m'], abs=1e-12)
        assert math.degrees(got.theta_b_rad) == pytest.approx(want['theta_b_deg'], abs=1e-9)
        assert got.h_band_m == pytest.approx(BAND_SIGMAS * want['h_sigma_m'], abs=1e-12)
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
