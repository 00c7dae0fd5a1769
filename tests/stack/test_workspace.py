"""The workspace contract: the ament_python packages, `ros2 run` lookup, a ROS-free core."""
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from repo_layout import PYTHON_PACKAGES

REPO = Path(__file__).resolve().parents[2]
PACKAGES = PYTHON_PACKAGES


@pytest.mark.parametrize('pkg', PACKAGES)
def test_ament_python_package_layout(pkg):
    root = ET.parse(REPO / 'src' / pkg / 'package.xml').getroot()
    assert root.tag == 'package' and root.get('format') == '3'
    assert root.findtext('name') == pkg
    assert root.find('export/build_type').text == 'ament_python'
    cfg = (REPO / 'src' / pkg / 'setup.cfg').read_text()
    assert f'install_scripts=$base/lib/{pkg}' in cfg  # where `ros2 run` looks
    assert (REPO / 'src' / pkg / 'resource' / pkg).exists()


def ros2_cmd():
    exe = shutil.which('ros2')
    if exe is None:
        pytest.skip('no ros2 on PATH (source tools/env.sh)')
    return exe


def test_ros2_run_finds_installed_executables():
    out = subprocess.run([ros2_cmd(), 'run', 'rftgls_core', 'rftgls', 'capacity', '--help'],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert '--theta-l1' in out.stdout


@pytest.mark.parametrize('args, message', [
    (['run', 'rftgls_core', 'no_such_exe'], 'No executable found'),
    (['run', 'no_such_pkg', 'x'], "Package 'no_such_pkg' not found"),
    (['topic', 'list'], 'usage'),
])
def test_ros2_run_errors(args, message):
    out = subprocess.run([ros2_cmd()] + args, capture_output=True, text=True, timeout=30)
    assert out.returncode != 0 and message in out.stderr


def test_ros2_run_lookup_order_args_and_loopback(tmp_path):
    """A throwaway ament prefix: first prefix wins, args pass through, DDS stays on loopback."""
    def make_prefix(name, text):
        prefix = tmp_path / name
        (prefix / 'share/ament_index/resource_index/packages').mkdir(parents=True)
        (prefix / 'share/ament_index/resource_index/packages/demo_pkg').touch()
        exe = prefix / 'lib/demo_pkg/show'
        exe.parent.mkdir(parents=True)
        exe.write_text(f'#!/bin/sh\necho "{text} $ROS_AUTOMATIC_DISCOVERY_RANGE $*"\n')
        exe.chmod(0o755)
        return prefix
    first, second = make_prefix('a', 'first'), make_prefix('b', 'second')
    env = {k: v for k, v in os.environ.items() if k != 'ROS_AUTOMATIC_DISCOVERY_RANGE'}
    env['AMENT_PREFIX_PATH'] = f'{first}:{second}'
    out = subprocess.run([str(REPO / 'tools/ros2'), 'run', 'demo_pkg', 'show', 'x y', '--z'],
                         capture_output=True, text=True, env=env, timeout=30)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'first LOCALHOST x y --z'


def test_core_imports_without_ros():
    """Every module of rftgls_core imports with rclpy (and every ROS package) made unimportable."""
    script = r'''
import importlib, pkgutil, sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs',
                                  'diagnostic_msgs', 'rosidl_parser', 'rosbags'):
            raise ImportError(f'ROS import of {name} in rftgls_core')
sys.meta_path.insert(0, Block())
import rftgls_core
names = [m.name for m in pkgutil.walk_packages(rftgls_core.__path__, 'rftgls_core.')]
for n in names:
    importlib.import_module(n)
print(len(names))
'''
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) > 10
