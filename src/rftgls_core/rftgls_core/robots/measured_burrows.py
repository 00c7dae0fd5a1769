"""Burrows measured on a real robot: the evidence a burrow model is checked against and a
modelled pose's band must cover.

MiniRQuad in M90 sand, the paper's Table II (Huh et al., RA-L 2023, sec. VI-B): the final
body pitch and height of p above the surface after each burrow mode, mean and standard
deviation of six trials. The leg angles of each mode are in multibody.gaits.TABLE_II_BURROWS.
Units SI: m, rad.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class MeasuredBurrow:
    """h_m, h_sd_m: height of p above the surface after the burrow, mean and standard
    deviation; theta_b_rad, theta_b_sd_rad: body pitch, mean and SD (positive: axle end above
    p); trials: how many burrows were measured; source: where the numbers come from."""

    h_m: float
    h_sd_m: float
    theta_b_rad: float
    theta_b_sd_rad: float
    trials: int
    source: str


_TABLE_II = 'Huh et al. RA-L 2023, Table II (MiniRQuad, M90 sand, 6 trials)'


def _table_ii(theta_b_deg: float, theta_b_sd_deg: float, h_m: float, h_sd_m: float):
    return MeasuredBurrow(h_m, h_sd_m, math.radians(theta_b_deg), math.radians(theta_b_sd_deg),
                          6, _TABLE_II)


# robot -> burrow mode -> its burrow energy over the 8 s window, idle power removed, relative
# to SH (the paper's Fig. 10(a) and sec. VI-B: DH 1.32 and DL 1.26 times SH)
MEASURED_ENERGY_RATIOS: dict[str, dict[str, float]] = {
    'minirquad': {'DH': 1.32, 'DL': 1.26, 'SH': 1.0},
}

# robot -> burrow mode -> its measurement (pitch in deg and height in m as the paper prints
# them, 34 +- 1 mm written 0.034 +- 0.001 m)
MEASURED_BURROWS: dict[str, dict[str, MeasuredBurrow]] = {
    'minirquad': {'DH': _table_ii(5.0, 0.4, 0.034, 0.001),
                  'DL': _table_ii(8.9, 0.7, 0.036, 0.002),
                  'SH': _table_ii(2.4, 0.7, 0.047, 0.002)},
}


def measured_burrow(robot: str, mode: str) -> MeasuredBurrow | None:
    """The measured burrow of this robot and mode, None when it was never measured."""
    return MEASURED_BURROWS.get(robot, {}).get(mode)
