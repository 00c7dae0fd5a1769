"""A walk never outlives its commander: the bridge keeps the gait the MCU runs with its
deadline (gaits.GaitHold, GaitCommand.valid_until) and stands the robot when a moving gait is
not refreshed in time, without restarting a gait that is refreshed. ROS-free rules first, then
the real bridge node over a real pty with the compiled firmware (and the Python reference MCU
in the campaign): a refreshed walk stays one SET_GAIT, an abandoned one stands the robot."""
from __future__ import annotations

import math
import time

import pytest
from builtin_interfaces.msg import Time

from minirquad_driver.gaits import GaitHold
from minirquad_driver.protocol import messages as m

NOW = 1.7e9


def test_a_refresh_moves_the_deadline_and_sends_nothing():
    g = GaitHold()
    assert g.command('walk', NOW + 0.25, NOW) == 'walk'
    assert g.command('walk', NOW + 0.45, NOW + 0.2) is None      # same gait: no restart
    assert g.due(NOW + 0.44) is None
    assert g.due(NOW + 0.45) == 'stand' and g.running == 'stand'
    assert g.due(NOW + 1.0) is None                              # standing: nothing more


def test_another_gait_or_a_gait_after_the_mcu_left_it_is_sent():
    g = GaitHold()
    assert g.command('walk', 0.0, NOW) == 'walk'                  # no limit
    assert g.due(NOW + 1e6) is None
    assert g.command('reverse', NOW + 0.25, NOW) == 'reverse'
    g.left(NOW + 0.05)                                            # a burrow, legs, e-stop
    assert g.command('reverse', NOW + 0.35, NOW + 0.1) == 'reverse'
    assert g.command('stand', 0.0, NOW + 0.2) == 'stand'
    assert g.command('stand', 0.0, NOW + 0.3) == 'stand'          # a stand is always sent


def test_a_walk_sent_before_a_burrow_but_received_after_it_is_dropped():
    """DDS orders per topic: the walk refresh published just before a burrow can arrive after
    the burrow (another topic). Judged by its stamp against the burrow's receipt."""
    g = GaitHold()
    assert g.command('walk', NOW + 0.25, NOW, sent_at=NOW) == 'walk'
    g.left(NOW + 0.012)                                     # the burrow, received
    assert g.command('walk', NOW + 0.26, NOW + 0.013, sent_at=NOW + 0.010) is None
    assert g.running is None and g.due(NOW + 1.0) is None   # nothing to stand: it burrows
    # A walk commanded after the burrow (the next cycle) is sent.
    assert g.command('walk', NOW + 5.25, NOW + 5.0, sent_at=NOW + 5.0) == 'walk'


def test_a_walk_already_past_its_deadline_never_starts_and_stands_a_walking_robot():
    g = GaitHold()
    assert g.command('walk', NOW - 0.01, NOW) is None and g.running is None
    assert g.command('walk', NOW + 0.25, NOW) == 'walk'
    assert g.command('walk', NOW + 0.3, NOW + 0.31) == 'stand'



def test_the_commands_bridge_node_logs_are_named():
    # bridge_node logs each gait, burrow and e-stop it sends ("to the MCU: ..."): the record
    # of what the robot was told (the stack tests read it, test_tug_safety_e2e.py).
    from minirquad_driver.bridge_node import command_text
    from minirquad_driver.gaits import GAITS
    assert command_text(GAITS['walk']) == 'gait walk'
    assert command_text(GAITS['stand']) == 'gait stand'
    custom = m.SetGait(m.GaitKind.CLOCK, period=1.0, duty=0.5, sweep=1.0, down=0.0,
                       phases=(0.0, 0.5, 0.5, 0.0))
    assert command_text(custom) == 'gait clock (custom)'
    assert command_text(m.Burrow(m.BurrowMode.DL)) == 'burrow DL'
    assert command_text(m.EStop(True)) == 'e-stop engaged'
    assert command_text(m.EStop(False)) == 'e-stop released'


def _valid_until(node, seconds: float) -> Time:
    ns = node.get_clock().now().nanoseconds + round(seconds * 1e9)
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def _mode(h) -> int | None:
    tel = h.node.core.last_telemetry
    return None if tel is None else tel.mode


@pytest.mark.realtime
def test_an_abandoned_walk_stands_the_robot_and_a_refreshed_one_is_one_command(sim, harness):
    from rftgls_interfaces.msg import GaitCommand
    s = sim.start()
    h = harness(str(s.link))
    pub = h.probe.create_publisher(GaitCommand, 'gait/command', 10)
    assert h.spin_until(lambda: h.joints, 15.0), 'no telemetry'
    assert h.spin_until(lambda: pub.get_subscription_count() > 0, 5.0)
    sent0 = h.node.core.counters.commands_sent
    # A commander walking the robot: 0.25 s deadlines refreshed every 20 ms for 1.5 s.
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        pub.publish(GaitCommand(gait=GaitCommand.WALK, valid_until=_valid_until(h.probe, 0.25)))
        h.spin(0.02)
    assert _mode(h) == m.Mode.WALKING
    assert h.node.core.counters.commands_sent - sent0 == 1, 'a refresh restarted the gait'
    # The commander stops: the robot stands within the deadline and one watch period (50 ms),
    # plus a telemetry period and scheduling.
    stopped = time.monotonic()
    assert h.spin_until(lambda: _mode(h) == m.Mode.IDLE, 2.0), _mode(h)
    took = time.monotonic() - stopped
    assert took < 0.25 + 0.05 + 0.25, took
    assert h.node.gait_hold.running == 'stand'
    # A walk without a deadline (an operator's: until told otherwise) keeps walking.
    pub.publish(GaitCommand(gait=GaitCommand.WALK))
    assert h.spin_until(lambda: _mode(h) == m.Mode.WALKING, 3.0)
    h.spin(1.0)
    assert _mode(h) == m.Mode.WALKING and math.isinf(h.node.gait_hold.until)
