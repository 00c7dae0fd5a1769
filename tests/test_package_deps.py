"""Each ament_python package declares (package.xml) exactly what its Python imports need.

Every module a package's files import (its Python package, setup.py and launch files; parsed
with ast, so optional imports inside functions or try blocks count too) must be a dependency
with its rosdep key, and every declared run dependency must be imported somewhere. The Python
standard library, the package itself and setuptools (the ament_python build type brings it)
are exempt. No ROS needed.
"""
from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from repo_layout import PYTHON_PACKAGES

REPO = Path(__file__).resolve().parents[1]
PACKAGES = PYTHON_PACKAGES
# import name -> rosdep key (the keys of rosdep's python.yaml; python3-numba, python3-dask and
# python3-rosbags could not be checked against a rosdep database on these machines). ROS
# packages (rclpy, *_msgs, *_interfaces, launch, ...) are their own key.
ROSDEP = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'h5py': 'python3-h5py',
    'matplotlib': 'python3-matplotlib', 'numba': 'python3-numba', 'tqdm': 'python3-tqdm',
    'dask': 'python3-dask', 'cv2': 'python3-opencv', 'serial': 'python3-serial',
    'yaml': 'python3-yaml', 'rosbags': 'python3-rosbags',
}
ROS = {'rclpy', 'launch', 'launch_ros', 'ament_index_python', 'builtin_interfaces', 'xacro'}
EXEMPT = {'setuptools'}
RUN_TAGS = ('depend', 'exec_depend')


def imports(files, root: Path = REPO) -> dict[str, set[str]]:
    """Top-level module -> files (relative to root) importing it (absolute imports only)."""
    out: dict[str, set[str]] = {}
    for f in files:
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for n in names:
                out.setdefault(n.split('.')[0], set()).add(str(f.relative_to(root)))
    return out


def named(files, names: set[str]) -> set[str]:
    """Which of `names` appear as a string constant in the files: a package whose programs
    are started by name (a launch file's Node(package=...), `ros2 run PKG ...`) is used at run
    time without being imported."""
    found = set()
    for f in files:
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Constant) and node.value in names:
                found.add(node.value)
    return found


def key_of(module: str) -> str | None:
    if module in ROSDEP:
        return ROSDEP[module]
    if module in ROS or module.startswith('rftgls_') or module.endswith(
            ('_msgs', '_srvs', '_interfaces')) or module.startswith('minirquad_'):
        return module
    return None


def package_files(pkg: str) -> list[Path]:
    root = REPO / 'src' / pkg
    return [f for f in root.rglob('*.py') if 'samples' not in f.parts]


def declared(pkg: str) -> set[str]:
    tree = ET.parse(REPO / 'src' / pkg / 'package.xml')
    return {e.text.strip() for tag in RUN_TAGS for e in tree.getroot().iter(tag) if e.text}


@pytest.mark.parametrize('pkg', PACKAGES)
def test_package_xml_matches_imports(pkg):
    used = {m: fs for m, fs in imports(package_files(pkg)).items()
            if m not in sys.stdlib_module_names and m != pkg and m not in EXEMPT}
    unknown = sorted(m for m in used if key_of(m) is None)
    assert not unknown, f'{pkg}: no rosdep key known for {unknown}: add it to ROSDEP'
    keys = {key_of(m): m for m in used}
    have = declared(pkg)
    missing = {k: sorted(used[m])[0] for k, m in keys.items() if k not in have}
    assert not missing, f'{pkg}/package.xml lacks <exec_depend> for (key: importing file) ' \
                        f'{missing}'
    unused = sorted(have - set(keys) - named(package_files(pkg), have))
    assert not unused, f'{pkg}/package.xml declares {unused}, which no file imports'


def test_the_scan_sees_every_kind_of_import(tmp_path):
    f = tmp_path / 'mod.py'
    f.write_text('import numpy as np\nfrom cv2 import aruco\nfrom . import x\n'
                 'import os.path\ndef g():\n    import serial\n')
    found = imports([f], root=tmp_path)
    assert set(found) == {'numpy', 'cv2', 'os', 'serial'}          # relative import skipped
    assert {key_of(m) for m in found if m != 'os'} == {'python3-numpy', 'python3-opencv',
                                                       'python3-serial'}
    assert key_of('some_unknown_lib') is None
