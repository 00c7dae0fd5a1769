"""`colcon test --packages-select minirquad_driver`: the repository's unit tests of this package
and the linters `make lint` runs on it (tests/colcon_package.py)."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / 'tests'))
from colcon_package import package_checks  # noqa: E402

test_unit_tests_of_the_package, test_ruff, _ = package_checks('minirquad_driver', [
    'tests/driver/test_codec.py',
    'tests/driver/test_crc_cobs.py',
    'tests/driver/test_transport.py',
    'tests/driver/test_energy.py',
    'tests/driver/test_ina219.py',
])
