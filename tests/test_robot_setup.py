"""tools/robot_setup.sh skips the workspace's tf2_msgs exactly when the ROS install has its
own (a COLCON_IGNORE colcon honours), and takes the skip back when it has none. Run on a copy
of the workspace's src folder with a stand-in ROS prefix; no ROS needed."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / 'tools' / 'robot_setup.sh'


def run(prefix: Path, src: Path) -> str:
    proc = subprocess.run(['sh', str(SCRIPT), '--skip-only', str(prefix), str(src)],
                          capture_output=True, text=True, check=True)
    return proc.stdout


def test_tf2_msgs_is_skipped_only_where_ros_has_it(tmp_path):
    src = tmp_path / 'src'
    shutil.copytree(REPO / 'src' / 'tf2_msgs', src / 'tf2_msgs')
    ros = tmp_path / 'opt_ros_jazzy'
    (ros / 'share').mkdir(parents=True)
    assert run(ros, src) == '' and not (src / 'tf2_msgs' / 'COLCON_IGNORE').exists()
    (ros / 'share' / 'tf2_msgs').mkdir()
    (ros / 'share' / 'tf2_msgs' / 'package.xml').write_text('<package/>')
    assert 'tf2_msgs' in run(ros, src)
    assert (src / 'tf2_msgs' / 'COLCON_IGNORE').exists()
    shutil.rmtree(ros / 'share' / 'tf2_msgs')
    run(ros, src)
    assert not (src / 'tf2_msgs' / 'COLCON_IGNORE').exists()


def test_the_real_workspace_builds_its_own_tf2_msgs_here():
    # This machine has no ROS install: the stand-in must not be skipped.
    assert not (REPO / 'src' / 'tf2_msgs' / 'COLCON_IGNORE').exists()
