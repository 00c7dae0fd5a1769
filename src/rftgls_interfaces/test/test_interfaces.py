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
    assert WinchCommand.get_fields_and_field_types() == {
        'header': 'std_msgs/Header', 'speed_mps': 'double',
        'valid_until': 'builtin_interfaces/Time'}
    # The serial protocol's BURROW mode byte (src/minirquad_driver/PROTOCOL.md: 0 UNBURROW,
    # 1 DH, 2 DL, 3 SH) and the named gaits.
    assert (BurrowCommand.UNBURROW, BurrowCommand.DH, BurrowCommand.DL,
            BurrowCommand.SH) == (0, 1, 2, 3)
    assert (GaitCommand.STAND, GaitCommand.WALK, GaitCommand.REVERSE,
            GaitCommand.BOUND) == (0, 1, 2, 3)
    assert (LinkState.OK, LinkState.STALE) == (0, 1)
    assert math.isnan(float('nan')) and QueryCapacity.Request is not None


def test_walk_burrow_tug_action():
    from rftgls_interfaces.action import WalkBurrowTug
    from rftgls_interfaces.msg import CycleOutcome
    assert WalkBurrowTug.Goal.get_fields_and_field_types() == {'sled_mass_kg': 'double',
                                                               'cycles': 'uint32'}
    assert WalkBurrowTug.Result.get_fields_and_field_types()['cycles'] == \
        'sequence<rftgls_interfaces/CycleOutcome>'
    assert {'state', 'margin_n', 'capacity_lower_n'} <= set(
        WalkBurrowTug.Feedback.get_fields_and_field_types())
    assert (CycleOutcome.OK, CycleOutcome.REFUSED, CycleOutcome.STOPPED, CycleOutcome.ABORTED,
            CycleOutcome.CANCELLED) == (1, 2, 3, 4, 5)
