#!/bin/sh
# Robot install on Ubuntu 24.04 with ROS 2 Jazzy (/opt/ros/jazzy): README.md, "On a robot".
#
#   tools/robot_setup.sh            # from the repository root, ROS sourced or not
#
# 1. The workspace's stand-ins for packages a ROS install already has (tf2_msgs, built here
#    only because no pip wheel exists) are skipped: a COLCON_IGNORE in each whose package is
#    in the ROS prefix (share/<name>/package.xml), removed again where it is not.
# 2. rosdep installs every dependency it has a system package for; the pip-only keys are
#    skipped there and installed in step 3 instead (Ubuntu 24.04 refuses system-wide pip).
# 3. A venv that sees the system packages (--system-site-packages) gets what rosdep cannot
#    give: rosbags and ruff (rosdep's *-pip keys). Nothing else is pip-installed, so the
#    system numpy, scipy, OpenCV stay the ones every ROS package uses.
# 4. `python -m colcon build` with that venv's Python, so the nodes' scripts run in it.
set -eu
ROS_PREFIX=${ROS_PREFIX:-/opt/ros/${ROS_DISTRO:-jazzy}}
cd "$(dirname "$0")/.."
VENV=${VENV:-.venv-robot}

skip_system_packages() {    # $1: ROS prefix, $2: the workspace's src folder
    for pkg in tf2_msgs; do
        if [ -f "$1/share/$pkg/package.xml" ]; then
            touch "$2/$pkg/COLCON_IGNORE"
            echo "robot_setup: $pkg: using $1's, skipping the workspace's copy"
        else
            rm -f "$2/$pkg/COLCON_IGNORE"
        fi
    done
}

if [ "${1:-}" = "--skip-only" ]; then       # step 1 alone (tests, or after a ROS upgrade)
    skip_system_packages "${2:-$ROS_PREFIX}" "${3:-src}"
    exit 0
fi
[ -f "$ROS_PREFIX/setup.sh" ] || { echo "robot_setup: no ROS at $ROS_PREFIX" >&2; exit 1; }
# shellcheck disable=SC1091
. "$ROS_PREFIX/setup.sh"
skip_system_packages "$ROS_PREFIX" src
rosdep install --from-paths src --ignore-src -y \
    --skip-keys "python3-rosbags-pip python3-ruff-pip"
python3 -m venv --system-site-packages "$VENV"
"$VENV/bin/python" -m pip install rosbags ruff
cd ros2_ws && "../$VENV/bin/python" -m colcon build --symlink-install
echo "robot_setup: done; in each shell: . $ROS_PREFIX/setup.sh && . $VENV/bin/activate && . ros2_ws/install/setup.sh"
