"""Energy integration on MCU timestamps against analytic integrals."""
import math

import pytest

from minirquad_driver.energy import EnergyIntegrator
from minirquad_driver.mcu_clock import McuClock


def _power(t):
    """2 W mean with a 1.5 Hz ripple of 0.5 W: E(T) = 2T + 0.5 (1 - cos wT) / w."""
    return 2.0 + 0.5 * math.sin(2 * math.pi * 1.5 * t)


def _exact(t0, t1):
    w = 2 * math.pi * 1.5
    return 2.0 * (t1 - t0) + 0.5 * (math.cos(w * t0) - math.cos(w * t1)) / w


def _feed(integ, t_start_ms, n, period_ms, skip=()):
    for k in range(n):
        if k in skip:
            continue
        t_ms = t_start_ms + k * period_ms
        integ.add(t_ms & 0xFFFFFFFF, _power(k * period_ms * 1e-3))


def test_trapezoid_matches_the_analytic_integral():
    integ = EnergyIntegrator()
    _feed(integ, 0, 1001, 10)                          # 10 s at 100 Hz
    # Trapezoid error bound: T dt^2 max|P''| / 12 = 10 * 1e-4 * 44.4 / 12 = 3.7e-4 J.
    assert integ.energy_j == pytest.approx(_exact(0, 10.0), abs=4e-4)
    assert integ.gaps == 0 and integ.integrated_s == pytest.approx(10.0)


def test_counter_wrap_is_seamless():
    integ = EnergyIntegrator()
    _feed(integ, 2**32 - 3000, 1001, 10)              # crosses 2**32 after 3 s
    assert integ.energy_j == pytest.approx(_exact(0, 10.0), abs=4e-4)
    assert integ.gaps == 0 and integ.resets == 0


def test_never_integrates_across_a_gap():
    integ = EnergyIntegrator()
    _feed(integ, 0, 1001, 10, skip=range(300, 400))   # 1 s hole from 2.99 s to 4.00 s
    expected = _exact(0, 2.99) + _exact(4.0, 10.0)
    assert integ.energy_j == pytest.approx(expected, abs=4e-4)
    assert integ.gaps == 1
    assert integ.missing_s == pytest.approx(1.01)


def test_one_dropped_sample_is_bridged():
    integ = EnergyIntegrator()
    _feed(integ, 0, 1001, 10, skip={500})
    assert integ.gaps == 0
    assert integ.energy_j == pytest.approx(_exact(0, 10.0), abs=1e-3)


def test_reset_keeps_energy_and_restarts_the_baseline():
    integ = EnergyIntegrator()
    _feed(integ, 50_000, 501, 10)                     # 5 s
    before = integ.energy_j
    # MCU reboots: its clock restarts near zero. Nothing is integrated across the reset.
    for k in range(101):
        integ.add(20 + k * 10, 3.0)
    assert integ.resets == 1
    assert integ.energy_j == pytest.approx(before + 3.0 * 1.0)


def test_duplicates_and_nan_are_skipped():
    integ = EnergyIntegrator()
    integ.add(0, 1.0)
    integ.add(10, 1.0)
    integ.add(10, 100.0)      # duplicate stamp
    integ.add(20, float('nan'))
    integ.add(30, 1.0)
    integ.add(40, 1.0)
    assert integ.rejected == 1
    assert integ.energy_j == pytest.approx(0.01 + 0.01)


def test_mcu_clock_unwraps_and_detects_resets():
    c = McuClock()
    assert c.update(2**32 - 5) == (2**32 - 5, True)
    assert c.update(5) == (2**32 + 5, False)
    assert c.wraps == 1
    t, new = c.update(3)           # backwards: a reset
    assert new and c.resets == 1 and t == 3
