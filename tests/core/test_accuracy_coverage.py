"""The speed/accuracy/coverage numbers count every query, also where the reference has none."""
from __future__ import annotations

import math

import pytest

from rftgls_core import accuracy as acc


def _rec(status, cap, reason='', twist=(1.0, 0.0, 0.0)):
    return acc.Record('prototype', 'cfg', 'direct', 400, 24, (0.02, 0, 0, 0), 'forward', 0.0,
                      status, cap, twist if cap is not None else None, 0.001, reason)


def test_coverage_counts_reference_gaps_and_outcomes():
    ref = [_rec('ok', 2.0), _rec('ok', 4.0), _rec('unsupported', None, 'origin_outside'),
           _rec('ok', 1.0)]
    out = [_rec('ok', 2.2), _rec('degenerate', None, 'no_root'), _rec('unsupported', None,
           'origin_outside'), _rec('ok', 1.0)]
    s = acc.summarise(out, ref)
    assert s.queries == 4 and s.ref_no_value == 1
    assert s.answered_pct == pytest.approx(50.0)
    assert s.answered_where_ref_pct == pytest.approx(100.0 * 2 / 3)   # 2 of the 3 ref answers
    assert s.status_agree_pct == pytest.approx(75.0)                  # the no_root differs
    assert s.outcomes == {'degenerate:no_root': 1, 'ok': 2, 'unsupported:origin_outside': 1}
    assert s.compared == 2 and s.cap_over_pct_worst == pytest.approx(10.0)


def test_agreement_report_has_the_issue_numbers():
    # A small run (2 states, a 10^4-twist reference) of what `rftgls chart agreement` reports.
    r = acc.agreement('minirquad', 2, seed=1, reference_twists=10_000)
    assert len(r['rows']) == 2 and r['error_floor_N'] == pytest.approx(0.05 * 0.296 * 9.81)
    # the reference states its own error bound (local re-sampling, surfaces/brute_force.py)
    assert r['reference_err_N_worst'] is not None and 0.0 <= r['reference_err_N_worst'] < 1e-3
    for row in r['rows']:
        ref = row['brute-force']
        assert (ref['error_N'] is None) == (ref['capacity_N'] is None)
    for m in acc.AGREEMENT_METHODS:
        s = r['summary'][m]
        assert {'status_agree_pct', 'degenerate_pct', 'cap_err_pct_p95',
                'cap_over_pct_worst'} <= set(s)
        assert s['degenerate_pct'] == 0.0
        for row in r['rows']:
            assert row[m]['status'] == row['brute-force']['status']
            if row[m]['capacity_N'] is not None:
                assert math.isclose(row[m]['capacity_N'], row['brute-force']['capacity_N'],
                                    rel_tol=0.03)
