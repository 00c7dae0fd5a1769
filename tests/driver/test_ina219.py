"""INA219 register conversions against the datasheet (TI SBOS448G) LSBs.

Reference values: shunt 10 uV/LSB, bus 4 mV/LSB in bits 15..3, Cal = 4096 with a 0.1 ohm
shunt gives 0.1 mA/LSB current and 2 mW/LSB power (Adafruit 32V_2A preset).
"""
import pytest

from minirquad_driver import ina219
from minirquad_driver.protocol.messages import Power


def test_current_lsb_of_the_adafruit_default_calibration():
    assert ina219.current_lsb(4096, 0.1) == pytest.approx(1e-4)      # 0.1 mA
    assert 20 * ina219.current_lsb(4096, 0.1) == pytest.approx(2e-3)  # 2 mW
    assert ina219.current_lsb(10240, 0.1) == pytest.approx(40e-6)    # 32V_1A: 40 uA
    assert ina219.current_lsb(8192, 0.1) == pytest.approx(50e-6)     # 16V_400mA: 50 uA


def test_hand_computed_registers_convert_to_si():
    # 7.4 V bus: 7.4 / 4 mV = 1850 counts -> (1850 << 3) | CNVR = 14802.
    # 100 mA through 0.1 ohm = 10 mV = 1000 shunt LSBs; current = 1000 * 4096 / 4096 = 1000;
    # power = 1000 * 1850 / 5000 = 370 LSBs = 0.740 W.
    reg = Power(bus=14802, shunt=1000, current=1000, power=370, cal=4096)
    r = ina219.reading_from(reg)
    assert r.bus_voltage == pytest.approx(7.4)
    assert r.shunt_voltage == pytest.approx(0.010)
    assert r.current == pytest.approx(0.1)
    assert r.power == pytest.approx(0.74)
    assert 370 * 20 * ina219.current_lsb(4096) == pytest.approx(r.power)
    assert not r.chip_reset


def test_simulated_chip_produces_those_registers():
    assert ina219.registers_from(7.4, 0.1) == Power(14802, 1000, 1000, 370, 4096)


def test_negative_current_and_reset_chip():
    r = ina219.reading_from(ina219.registers_from(7.0, -0.25))
    assert r.current == pytest.approx(-0.25)
    assert r.power == pytest.approx(-1.75)
    # Cal read back as 0: the chip reset; current comes from shunt / R instead.
    reset = ina219.reading_from(Power(bus=14802, shunt=1000, current=0, power=0, cal=0))
    assert reset.chip_reset
    assert reset.current == pytest.approx(0.1)
