"""The robot's motion commands as the stack's commanders (behavior_node, teleop) send them to
bridge_node, each with the deadline that keeps it from outliving its sender.

- ``winch_command``: the reel-in set-point; a reel-in carries when its evidence runs out
  (``valid_until``), which the MCU enforces as the WINCH hold.
- ``gait_command``: a named gait; a moving one carries ``valid_until`` = now + hold, and its
  commander republishes it while it wants the robot to move, so the bridge stands the robot
  once the commander stops (crashed or stalled).
Deadlines are taken on the monotonic clock and sent in ROS time (stamps.py).
"""
from __future__ import annotations

from rftgls_interfaces.msg import GaitCommand, WinchCommand

from .stamps import deadline_stamp, ns_stamp

GAIT_CODES = {'stand': GaitCommand.STAND, 'walk': GaitCommand.WALK,
              'reverse': GaitCommand.REVERSE, 'bound': GaitCommand.BOUND}


def gait_command(name: str, ros_now_ns: int, hold_s: float) -> GaitCommand:
    """``name`` (a GAIT_CODES key) stamped now; any gait but stand valid for ``hold_s``
    (s; 0: no limit, until another gait is commanded)."""
    msg = GaitCommand(gait=GAIT_CODES[name])
    msg.header.stamp = ns_stamp(ros_now_ns)
    if name != 'stand' and hold_s > 0.0:
        msg.valid_until = ns_stamp(ros_now_ns + round(hold_s * 1e9))
    return msg


def winch_command(speed_mps: float, valid_until_s: float, mono_now_s: float,
                  ros_now_ns: int) -> WinchCommand:
    """The set-point (m/s, reel-in positive) with the monotonic time its evidence runs out
    (s; 0: no limit of its own) as ROS time, stamped now."""
    msg = WinchCommand(speed_mps=float(speed_mps),
                       valid_until=deadline_stamp(valid_until_s, mono_now_s, ros_now_ns))
    msg.header.stamp = ns_stamp(ros_now_ns)
    return msg
