"""Between a node's two clocks: monotonic seconds for its decisions, ROS time on the wire.

A commander decides on ``time.monotonic()`` (a wall-clock step must not age or rejuvenate its
evidence) while the messages it reads and writes carry ROS time (``header.stamp``, the bridge's
mapping of the MCU's sample clock; ``WinchCommand.valid_until``). Both conversions go through
the offset between the two clocks read now, so a sample is as old as its stamp says and a
deadline is as far away as the decision made it.
"""
from __future__ import annotations

from builtin_interfaces.msg import Time


def stamp_ns(stamp: Time) -> int:
    """A ROS time message as integer nanoseconds."""
    return stamp.sec * 10**9 + stamp.nanosec


def is_unset(stamp: Time) -> bool:
    """The zero stamp: a sender that did not stamp its sample (read as "taken now")."""
    return stamp.sec == 0 and stamp.nanosec == 0


def stamp_s(stamp: Time) -> float:
    """A ROS time message as float seconds (whole seconds plus the fraction, so the fraction
    keeps its digits)."""
    return stamp.sec + stamp.nanosec * 1e-9


def ns_stamp(ns: int) -> Time:
    """Integer nanoseconds as a ROS time message."""
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def sample_time(stamp: Time, ros_now_ns: int, mono_now_s: float) -> float:
    """When a stamped sample was taken, on the monotonic clock (s): now minus its age by the
    stamp. An unset stamp (0) counts as taken now; a stamp ahead of ROS now as age 0."""
    if is_unset(stamp):
        return mono_now_s
    return mono_now_s - max(0.0, (ros_now_ns - stamp_ns(stamp)) * 1e-9)


def deadline_stamp(deadline_s: float, mono_now_s: float, ros_now_ns: int) -> Time:
    """A monotonic deadline (s) as ROS time; a deadline <= 0 ("no limit of its own") as the
    zero stamp, which the bridge reads as no hold."""
    if deadline_s <= 0.0:
        return Time()
    ns = ros_now_ns + round((deadline_s - mono_now_s) * 1e9)
    return ns_stamp(max(1, ns))   # a past deadline stays a deadline, never the "no limit" 0
