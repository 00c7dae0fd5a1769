"""Each ament_python package declares (package.xml) exactly what its Python imports need.

Every module a package's files import (its Python package, setup.py and launch files; parsed
with ast, so optional imports inside functions or try blocks count too) must be a dependency
with its rosdep key, and every declared run dependency must be imported somewhere; the files
of its test/ folder (what `colcon test` runs) must find theirs among the run and test
dependencies. The Python standard library, the package itself and setuptools (the
ament_python build type brings it) are exempt, and so are OPTIONAL modules: imported only
where a feature needs them, with no rosdep key, named in package.xml's comments. No ROS needed.
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
# import name -> rosdep key (checked against rosdistro: requirements/rosdep_keys.yaml,
# tests/test_rosdep_keys.py). ROS packages (rclpy, *_msgs, *_interfaces, launch, ...) are their
# own key.
ROSDEP = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'h5py': 'python3-h5py',
    'matplotlib': 'python3-matplotlib', 'numba': 'python3-numba', 'tqdm': 'python3-tqdm',
    'cv2': 'python3-opencv', 'serial': 'python3-serial', 'yaml': 'python3-yaml',
    'rosbags': 'python3-rosbags-pip', 'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis', 'urdf_parser_py': 'urdfdom_py',
    # llvmlite is numba's compiler backend, installed with it (Debian's python3-numba depends
    # on python3-llvmlite); the bench reads numba's target CPU from it.
    'llvmlite': 'python3-numba',
}
ROS = {'rclpy', 'launch', 'launch_ros', 'ament_index_python', 'builtin_interfaces', 'xacro'}
# colcon_package: the repository's tests/colcon_package.py, which each package's test/ takes its
# checks from (a package's colcon test runs the repository's tests anyway: no rosdep key).
EXEMPT = {'setuptools', 'colcon_package'}
OPTIONAL = {'dask'}      # distributed map builds only (rftgls_core/package.xml says so)
RUN_TAGS = ('depend', 'exec_depend')
TEST_TAGS = RUN_TAGS + ('test_depend',)


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


def package_files(pkg: str, tests: bool = False) -> list[Path]:
    """The package's Python files outside (or, tests=True, inside) its test/ folder."""
    root = REPO / 'src' / pkg
    return [f for f in root.rglob('*.py') if 'samples' not in f.parts
            and (f.relative_to(root).parts[0] == 'test') == tests]


def declared(pkg: str, tags=RUN_TAGS) -> set[str]:
    tree = ET.parse(REPO / 'src' / pkg / 'package.xml')
    return {e.text.strip() for tag in tags for e in tree.getroot().iter(tag) if e.text}


def _used(files, pkg: str) -> dict[str, set[str]]:
    return {m: fs for m, fs in imports(files).items()
            if m not in sys.stdlib_module_names and m != pkg and m not in EXEMPT | OPTIONAL}


@pytest.mark.parametrize('pkg', PACKAGES)
def test_test_folder_imports_are_declared(pkg):
    used = _used(package_files(pkg, tests=True), pkg)
    assert used or (REPO / 'src' / pkg / 'test').is_dir(), f'{pkg} has no test/ folder'
    unknown = sorted(m for m in used if key_of(m) is None)
    assert not unknown, f'{pkg}/test: no rosdep key known for {unknown}: add it to ROSDEP'
    have = declared(pkg, TEST_TAGS)
    missing = {key_of(m): sorted(fs)[0] for m, fs in used.items() if key_of(m) not in have}
    assert not missing, f'{pkg}/package.xml lacks <test_depend> for {missing}'


@pytest.mark.parametrize('pkg', PACKAGES)
def test_package_xml_matches_imports(pkg):
    used = _used(package_files(pkg), pkg)
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
