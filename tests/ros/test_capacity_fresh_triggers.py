"""capacity_node's choice of which trigger messages to answer (capacity/fresh_triggers.py),
without ROS: a trigger that waited past the limit is pending, not answered; the next fresh
one answers and clears it; the limit 0 answers everything."""
import pytest

from rftgls_ros.capacity.fresh_triggers import FreshTriggers


def test_a_trigger_within_the_limit_is_answered_and_nothing_stays_pending():
    f = FreshTriggers(0.01)
    assert f.arrived(0.0099, 'a', 1) is True
    assert f.pending is None and f.skipped == 0


def test_a_late_trigger_is_pending_and_a_later_one_replaces_it():
    f = FreshTriggers(0.01)
    assert f.arrived(0.02, 'a', 1) is False
    assert f.arrived(0.015, 'b', 2) is False
    assert f.skipped == 2
    p = f.take_pending()
    assert (p.stamp, p.source_ns) == ('b', 2)   # the newest skipped one is owed the answer
    assert f.take_pending() is None            # and only once


def test_a_fresh_trigger_after_late_ones_clears_what_was_pending():
    f = FreshTriggers(0.01)
    f.arrived(0.05, 'a', 1)
    assert f.arrived(0.001, 'b', 2) is True
    assert f.take_pending() is None


def test_limit_zero_answers_every_trigger_however_late():
    f = FreshTriggers(0.0)
    assert all(f.arrived(q, k, k) for k, q in enumerate((0.0, 0.5, 10.0)))
    assert f.skipped == 0


@pytest.mark.parametrize('bad', [-0.001, float('nan')])
def test_a_negative_or_nan_limit_is_refused(bad):
    with pytest.raises(ValueError, match='max_queue_s'):
        FreshTriggers(bad)
