"""INA219 register arithmetic (TI datasheet SBOS448G; Adafruit breakout, 0.1 ohm shunt).

Register LSBs: shunt voltage 10 uV (signed); bus voltage bits 15..3 at 4 mV (bit 1 CNVR,
bit 0 OVF); current LSB = 0.04096 / (Cal * R_shunt); power LSB = 20 * current LSB. The chip
computes current = shunt * Cal / 4096 and power = current * bus / 5000, in register units.
With Adafruit's default 32V_2A calibration (Cal = 4096): 0.1 mA and 2 mW per bit.

``registers_from`` is what the simulated MCU uses to produce honest, quantised readings;
``reading_from`` is the host-side conversion to SI.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .protocol.messages import Power

SHUNT_LSB_V = 10e-6
BUS_LSB_V = 4e-3
CAL_32V_2A = 4096
DEFAULT_SHUNT_OHM = 0.1
_SHUNT_FULL_SCALE = 32000     # +-320 mV at PGA /8
_CNVR = 0x2
_OVF = 0x1


def current_lsb(cal: int, r_shunt: float = DEFAULT_SHUNT_OHM) -> float:
    """Current register LSB in A for calibration value ``cal`` (datasheet eq. 1)."""
    return 0.04096 / (cal * r_shunt)


@dataclass(frozen=True)
class PowerReading:
    """One INA219 sample in SI units.

    bus_voltage: V at IN- (load side); shunt_voltage: V; current: A (positive into the load);
    power: W = bus_voltage * current, signed (the chip's power register is unsigned);
    chip_reset: True when Cal read back as 0 (current and power were then derived from the
    shunt voltage and R_shunt instead of the chip's registers); overflow: the OVF bit.
    """

    bus_voltage: float
    shunt_voltage: float
    current: float
    power: float
    chip_reset: bool = False
    overflow: bool = False


def registers_from(bus_voltage: float, current: float, cal: int = CAL_32V_2A,
                   r_shunt: float = DEFAULT_SHUNT_OHM) -> Power:
    """Quantised register values an INA219 would report for these true values."""
    shunt = round(current * r_shunt / SHUNT_LSB_V)
    overflow = abs(shunt) > _SHUNT_FULL_SCALE
    shunt = max(-_SHUNT_FULL_SCALE, min(_SHUNT_FULL_SCALE, shunt))
    bus_counts = max(0, min(0x1FFF, round(bus_voltage / BUS_LSB_V)))
    cur = int(shunt * cal / 4096)          # the chip truncates toward zero
    pwr = min(0xFFFF, abs(int(cur * bus_counts / 5000)))
    bus_reg = (bus_counts << 3) | _CNVR | (_OVF if overflow else 0)
    return Power(bus=bus_reg, shunt=shunt, current=cur, power=pwr, cal=cal)


def reading_from(reg: Power, r_shunt: float = DEFAULT_SHUNT_OHM) -> PowerReading:
    """Convert raw registers to SI. Never raises; a reset chip falls back to shunt / R."""
    bus_v = (reg.bus >> 3) * BUS_LSB_V
    shunt_v = reg.shunt * SHUNT_LSB_V
    if reg.cal == 0:
        current = shunt_v / r_shunt
        chip_reset = True
    else:
        current = reg.current * current_lsb(reg.cal, r_shunt)
        chip_reset = False
    power = bus_v * current
    if not math.isfinite(power):   # cannot happen with integer registers; belt and braces
        power = float('nan')
    return PowerReading(bus_voltage=bus_v, shunt_voltage=shunt_v, current=current, power=power,
                        chip_reset=chip_reset, overflow=bool(reg.bus & _OVF))
