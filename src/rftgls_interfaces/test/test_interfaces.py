"""The generated interfaces, as installed: every message and service imports with the fields
and constants the nodes rely on (the driver's command codes are the serial protocol's)."""
from __future__ import annotations

import math


def test_messages_and_constants():
    from rftgls_interfaces.msg import (
        AnchorEstimate,
        BurrowCommand,
        GaitCommand,
        LinkState,
        WinchCommand,
    )
    from rftgls_interfaces.srv import QueryCapacity
    assert {'capacity_n', 'capacity_lower_n', 'status', 'slip_twist'} <= set(
        AnchorEstimate.get_fields_and_field_types())
    assert WinchCommand.get_fields_and_field_types() == {'header': 'std_msgs/Header',
                                                         'speed_mps': 'double'}
    # The serial protocol's BURROW mode byte (src/minirquad_driver/PROTOCOL.md: 0 UNBURROW,
    # 1 DH, 2 DL, 3 SH) and the named gaits.
    assert (BurrowCommand.UNBURROW, BurrowCommand.DH, BurrowCommand.DL,
            BurrowCommand.SH) == (0, 1, 2, 3)
    assert (GaitCommand.STAND, GaitCommand.WALK, GaitCommand.REVERSE,
            GaitCommand.BOUND) == (0, 1, 2, 3)
    assert (LinkState.OK, LinkState.STALE) == (0, 1)
    assert math.isnan(float('nan')) and QueryCapacity.Request is not None
