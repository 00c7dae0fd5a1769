"""One diagnostics status, ROS-free: what a core object reports and a node turns into a
diagnostic_msgs/DiagnosticStatus on /diagnostics."""
from __future__ import annotations

from dataclasses import dataclass

OK, WARN, ERROR, STALE = 0, 1, 2, 3       # diagnostic_msgs/DiagnosticStatus levels


@dataclass(frozen=True)
class DiagStatus:
    """name: 'package: topic'; level: OK, WARN, ERROR or STALE; values: key -> text."""
    name: str
    level: int
    message: str
    values: dict
