"""Node parameters: declared once with a descriptor that states the unit (taken from the
name's suffix), the allowed range and whether it may change at run time; a bad parameter,
map or description file is a `ConfigError`, reported by `node_main.run_node` in one line."""
from __future__ import annotations

from typing import Any

# Unit suffixes of parameter names (longest first): the unit is in the name, and the
# descriptor repeats it for `ros2 param describe`.
UNIT_SUFFIXES = (('_m_s', 'm/s'), ('_rad2', 'rad^2'), ('_rad', 'rad'), ('_hz', 'Hz'),
                 ('_kg', 'kg'), ('_ohm', 'ohm'), ('_N', 'N'), ('_J', 'J'), ('_m', 'm'),
                 ('_s', 's'))
START_UP_ONLY = 'read at start-up only: restart the node to change it'


class ConfigError(ValueError):
    """A bad node parameter, map or description file: `run_node` reports it in one line and
    the executable exits with status 2."""


def unit_of(name: str) -> str:
    """The unit a parameter name ends in ('' when it has none: counts, ratios, names)."""
    return next((u for suffix, u in UNIT_SUFFIXES if name.endswith(suffix)), '')


def declare(node, name: str, default: Any, description: str = '', *,
            lo: float | None = None, hi: float | None = None, read_only: bool = True) -> Any:
    """Declare a parameter with a descriptor: description with its unit, the range [lo, hi]
    (rclpy rejects a value outside it, at start-up and at run time), and read_only unless
    the node applies run-time changes of it (a read-only one is rejected with a reason).
    Returns the value (default or override)."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    unit = unit_of(name)
    text = description + (f' [{unit}]' if unit else '')
    if read_only:
        text += f' ({START_UP_ONLY})'
    d = ParameterDescriptor(description=text, read_only=read_only)
    if lo is not None and hi is not None:
        if isinstance(default, bool):
            pass
        elif isinstance(default, int):
            d.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        elif isinstance(default, float):
            d.floating_point_range = [FloatingPointRange(from_value=float(lo),
                                                         to_value=float(hi), step=0.0)]
    return node.declare_parameter(name, default, d).value
