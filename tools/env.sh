# Source this file (". tools/env.sh") from the repository root after `make setup`:
# it activates the venv, overlays the colcon workspace and keeps DDS on loopback (discovery
# range LOCALHOST and the Fast DDS profile ros2_ws/params/fastdds_localhost.xml).
# Works in sh, bash and zsh.
if [ ! -f .venv/bin/activate ] || [ ! -f ros2_ws/install/setup.sh ]; then
    echo "tools/env.sh: run 'make setup' in the repository root first" >&2
    return 1 2>/dev/null || exit 1
fi
. .venv/bin/activate
# colcon's setup.sh reads its own location from this variable when sourced from sh.
COLCON_CURRENT_PREFIX="$PWD/ros2_ws/install" . ros2_ws/install/setup.sh
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
# Fast DDS profile: every DDS socket that receives is bound to 127.0.0.1 (Fast DDS 2.x reads
# FASTRTPS_DEFAULT_PROFILES_FILE, 3.x FASTDDS_DEFAULT_PROFILES_FILE).
export FASTRTPS_DEFAULT_PROFILES_FILE="${FASTRTPS_DEFAULT_PROFILES_FILE:-$PWD/ros2_ws/params/fastdds_localhost.xml}"
export FASTDDS_DEFAULT_PROFILES_FILE="${FASTDDS_DEFAULT_PROFILES_FILE:-$FASTRTPS_DEFAULT_PROFILES_FILE}"
# A fixed default keeps a hand-started stack together; tests pick their own ids.
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-42}"
export MPLBACKEND="${MPLBACKEND:-Agg}"
