#!/usr/bin/env bash
# Idempotent set-up: Debian's ROS 1 packages, the project venv (system site packages, so rospy imports),
# the project installed editable with its dev extras, and the catkin workspace.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

apt_packages=(ros-core python3-rospy python3-rosbag python3-sensor-msgs python3-trajectory-msgs
  ros-message-generation ros-message-runtime ros-std-msgs ros-geometry-msgs libstd-msgs-dev libgeometry-msgs-dev
  python3-diagnostic-msgs
  python3-geometry-msgs python3-std-msgs python3-rosgraph-msgs python3-std-srvs python3-tf2-msgs
  ros-robot-state-publisher python3-yaml
  chromium chromium-driver
  catkin rosbash iproute2)
missing=()
for pkg in "${apt_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  echo "setup: installing Debian packages: ${missing[*]}"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# Debian's rospy lives in /usr/bin/python3's dist-packages only; the venv must see it.
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
stamp=.venv/.setup_stamp
if [ ! -f "$stamp" ] || [ setup.py -nt "$stamp" ]; then
  echo "setup: pip install -e .[dev]"
  .venv/bin/python -m pip install -q --disable-pip-version-check -e ".[dev]"
  touch "$stamp"
fi

# catkin_make only when the workspace has never been built or a package file changed since.
if [ ! -f catkin_ws/devel/setup.bash ] || [ -n "$(find catkin_ws/src -newer catkin_ws/devel/setup.bash \( -name package.xml -o -name CMakeLists.txt \) -print -quit)" ]; then
  echo "setup: catkin_make"
  (cd catkin_ws && catkin_make -DPYTHON_EXECUTABLE="$repo/.venv/bin/python" >/tmp/catkin_make.log 2>&1) \
    || { tail -30 /tmp/catkin_make.log; echo "setup: catkin_make failed" >&2; exit 1; }
fi
echo "setup: ready ($repo/.venv)"
