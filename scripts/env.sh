# Source me: activates .venv and the colcon install space (bash).
_here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$_here/.venv/bin/activate"
set +u  # colcon's setup scripts read unset variables
# shellcheck disable=SC1091
source "$_here/install/local_setup.bash"
export ROS_LOG_DIR=${ROS_LOG_DIR:-$_here/log/ros}
# the executables, as `ros2 run mmg_tuner <exe>` would find them
export PATH="$_here/install/mmg_tuner/lib/mmg_tuner:$PATH"
