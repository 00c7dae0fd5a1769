"""Firmware test helpers: strategies.py of the driver tests on the path."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / 'driver'))    # strategies.py
