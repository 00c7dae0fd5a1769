"""The repository's packages, found from their package.xml files (one list for every test)."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / 'src'


def packages(build_type: str) -> tuple[str, ...]:
    """Names of the packages under src/ with this build type ('ament_python', 'ament_cmake')."""
    out = []
    for xml in sorted(SRC.glob('*/package.xml')):
        root = ET.parse(xml).getroot()
        if root.findtext('export/build_type') == build_type:
            out.append(root.findtext('name'))
    return tuple(out)


PYTHON_PACKAGES = packages('ament_python')
