#!/usr/bin/env bash
# Idempotent set-up: Debian's ROS 1 packages, the project venv (system site packages, so rospy imports),
# the project installed editable with its dev extras, the system Python's packages for vr_sim, and the catkin
# workspace.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

apt_packages=(ros-core python3-rospy python3-rosbag python3-sensor-msgs python3-trajectory-msgs
  ros-message-generation ros-message-runtime ros-std-msgs ros-geometry-msgs libstd-msgs-dev libgeometry-msgs-dev
  python3-diagnostic-msgs python3-actionlib python3-actionlib-msgs
  ros-actionlib-msgs libactionlib-msgs-dev ros-trajectory-msgs libtrajectory-msgs-dev
  python3-geometry-msgs python3-std-msgs python3-rosgraph-msgs python3-std-srvs python3-tf2-msgs
  ros-robot-state-publisher python3-yaml python3-wsproto
  python3-pip
  chromium chromium-driver nodejs openssl
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
  # --no-compile: pip would byte-compile every module it installs (scipy's, statsmodels' and pandas' own tests
  # among them), about half its CPU; Python compiles the modules a run imports, once, when it first imports them
  .venv/bin/python -m pip install -q --disable-pip-version-check --no-compile -e ".[dev]"
  touch "$stamp"
fi

# The system Python as a ROS user runs vr_sim's nodes with in their own workspace (the workspace test): what the
# package's rosdep keys name, by `pip install --user` into a user base of the repository's own (not the home
# directory's). Debian's python3-numpy and the like would do too, but the project venv sees the system's packages,
# and would then run on them.
user_base="$repo/.user_python"
if ! PYTHONUSERBASE="$user_base" /usr/bin/python3 -c "import numpy, scipy, matplotlib, pybullet, rosbags" 2>/dev/null; then
  echo "setup: pip install --user numpy scipy matplotlib pybullet rosbags for /usr/bin/python3 (in $user_base)"
  PYTHONUSERBASE="$user_base" PIP_ROOT_USER_ACTION=ignore /usr/bin/python3 -m pip install -q \
    --disable-pip-version-check --no-compile --no-warn-script-location --user --break-system-packages \
    numpy scipy matplotlib pybullet rosbags
fi

# The VR page's libraries (three.js, urdf-loader; IWER for the tests' emulated headset) and its linter and formatter
# (ESLint, Prettier) from the npm registry, at the versions and hashes of package-lock.json, into the package's web
# folder: the page's libraries are served from there, never from a CDN.
web=sim/study/views/vr/web
if [ ! -f "$web/node_modules/.package-lock.json" ] || [ "$web/package-lock.json" -nt "$web/node_modules/.package-lock.json" ]; then
  if ! command -v npm >/dev/null; then  # Debian's npm is its own package; NodeSource's nodejs carries one
    echo "setup: installing Debian's npm"
    $( [ "$(id -u)" -eq 0 ] || echo sudo ) apt-get install -y -qq npm >/dev/null
  fi
  echo "setup: npm ci (the VR page's three.js, urdf-loader, iwer; eslint, prettier)"
  (cd "$web" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error >/dev/null)
fi

# catkin_make only when the workspace has never been built or a package's build files changed since.
stamp=catkin_ws/devel/.setup_stamp
if [ ! -f "$stamp" ] || [ -n "$(find catkin_ws/src -newer "$stamp" \( -name package.xml -o -name CMakeLists.txt -o -name setup.py \) -print -quit)" ]; then
  echo "setup: catkin_make"
  (cd catkin_ws && catkin_make -DPYTHON_EXECUTABLE="$repo/.venv/bin/python" >/tmp/catkin_make.log 2>&1) \
    || { tail -30 /tmp/catkin_make.log; echo "setup: catkin_make failed" >&2; exit 1; }
  touch "$stamp"
fi
echo "setup: ready ($repo/.venv)"
