"""The tug time series (behavior/tug_series.py): samples in, CSV and PNG out, no ROS."""
from __future__ import annotations

import csv
import math

import pytest

from rftgls_ros.behavior.tug_series import TugSeries, _spans, plot_tug_series, write_tug_series


def test_spans_of_a_state():
    assert _spans([0, 1, 2, 3, 4], [False, True, True, False, True]) == [(1, 3), (4, 4)]
    assert _spans([0, 1], [False, False]) == []


def test_series_written_as_csv_and_png(tmp_path):
    s = TugSeries()
    # 2 s of tug at 10 Hz: tension rises to the capacity; one stale estimate in the middle.
    for i in range(21):
        t = 100.0 + 0.1 * i
        status = 'stale' if i == 10 else 'ok'
        cap = math.nan if status == 'stale' else 6.0
        pose = (-0.1 - 0.001 * i, 0.045, 0.17, -0.70, -0.35) if i else (math.nan,) * 5
        s.add(t, 0.3 * i, cap, 5.5, status, 'TUG' if i >= 3 else 'CHECK', pose)
    csv_path, png = write_tug_series(s, tmp_path, 'cycle_report', 0.9, 0.97)
    rows = list(csv.DictReader(csv_path.open()))
    assert len(rows) == 21
    assert float(rows[0]['t_s']) == 0.0 and float(rows[-1]['t_s']) == pytest.approx(2.0)
    assert rows[10]['status'] == 'stale' and rows[10]['capacity_n'] == 'nan'
    assert rows[3]['state'] == 'TUG' and float(rows[20]['tension_n']) == pytest.approx(6.0)
    # The pose each estimate was computed at, SI, NaN where it had none.
    assert float(rows[5]['phi_rad']) == pytest.approx(-0.105)
    assert [float(rows[5][k]) for k in ('h_m', 'theta_b_rad', 'theta_l1_rad',
                                        'theta_l2_rad')] == [0.045, 0.17, -0.70, -0.35]
    assert rows[0]['h_m'] == 'nan'
    assert png.name == 'cycle_report_tug.png'
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' and png.stat().st_size > 10_000


def test_nothing_recorded_writes_nothing(tmp_path):
    assert write_tug_series(TugSeries(), tmp_path, 'x') is None
    assert not list(tmp_path.iterdir())
    with pytest.raises(ValueError):
        plot_tug_series([], tmp_path / 'x.png')


def test_series_is_bounded():
    s = TugSeries(maxlen=5)
    for i in range(12):
        s.add(float(i), 1.0, 2.0, 1.5, 'ok', 'TUG')
    assert [x.t_s for x in s.samples] == [7.0, 8.0, 9.0, 10.0, 11.0]
