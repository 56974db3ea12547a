#!/usr/bin/env bash
# Idempotent: venvs on the Pythons of the ROS 1 distros, with the toolkit's requirements, the working tree on the
# path and the test tools:
#   .venv38   Python 3.8, ROS Noetic's (Ubuntu 20.04): required; none found is an error, never a skip.
#   .venv310  Python 3.10, Ubuntu 22.04's (ROS-O): made when one is found.
# The interpreter: $PYTHON38 / $PYTHON310, else the newest $(pyenv root)/versions/3.8.* / 3.10.*.
# ROS's Python packages (Debian's rospy, message packages) come from /usr/lib/python3/dist-packages through a .pth
# file: it puts them AFTER the venv's own packages, as a Noetic install's /opt/ros path sits after pip's, so the
# venv's numpy, PyYAML and Pillow are the ones imported, never Debian's builds for another Python.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

find_python() {  # find_python VERSION EXPLICIT: the interpreter's path, or nothing
  local version="$1" explicit="$2" pyenv_root candidate
  candidate="$explicit"
  if [ -z "$candidate" ]; then
    pyenv_root="$(pyenv root 2>/dev/null || echo "$HOME/.pyenv")"
    candidate="$(ls -d "$pyenv_root"/versions/"$version".*/bin/python 2>/dev/null | sort -V | tail -n 1 || true)"
  fi
  if [ -n "$candidate" ] && "$candidate" -c "import sys; sys.exit(sys.version_info[:2] != tuple(map(int, '$version'.split('.'))))" 2>/dev/null; then
    echo "$candidate"
  fi
}

make_venv() {  # make_venv VERSION DIR INTERPRETER
  local version="$1" dir="$2" python="$3" site
  if [ ! -x "$dir/bin/python" ]; then
    echo "setup_ros_pythons: creating $dir from $python"
    "$python" -m venv "$dir"
  fi
  site="$("$dir/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  if [ ! -f "$dir/.setup_stamp" ] || [ setup.py -nt "$dir/.setup_stamp" ]; then
    # Without ROS's path while pip runs: it would take Debian's Pillow (built for another Python) as installed.
    rm -f "$site/ros_dist_packages.pth"
    echo "setup_ros_pythons: pip install of setup.py's requirements, pytest, hypothesis, pytest-timeout (Python $version)"
    # setup.py's install_requires, and the working tree on the path by a .pth file: what `pip install -e .` gives
    # but for the egg-info it writes into the tree, which venvs made at the same time would both write.
    # --no-compile: as setup.sh's
    "$dir/bin/python" -m pip install -q --disable-pip-version-check --no-compile $(requirements "$dir/bin/python") \
      pytest hypothesis pytest-timeout
    echo "$repo" > "$site/vr_ros_toolkit.pth"
    touch "$dir/.setup_stamp"
  fi
  echo /usr/lib/python3/dist-packages > "$site/ros_dist_packages.pth"
}

requirements() {  # requirements PYTHON: setup.py's install_requires, one a line (read, not run)
  "$1" -c 'import ast, pathlib
call = next(node for node in ast.walk(ast.parse(pathlib.Path("setup.py").read_text()))
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "setup")
print("\n".join(ast.literal_eval(next(k.value for k in call.keywords if k.arg == "install_requires"))))'
}

py38="$(find_python 3.8 "${PYTHON38:-}")"
if [ -z "$py38" ]; then
  echo "setup_ros_pythons: no Python 3.8 found (set PYTHON38=/path/to/python3.8, or install one under" \
    "\$(pyenv root)/versions/3.8.*): the tests on ROS Noetic's Python cannot run" >&2
  exit 1
fi
py310="$(find_python 3.10 "${PYTHON310:-}")"
[ -n "$py310" ] || echo "setup_ros_pythons: no Python 3.10 found (PYTHON310 or \$(pyenv root)/versions/3.10.*): its tests are left out"
# The two venvs at once, each in a subshell that stops at its first failure: pip mostly waits on downloads.
make_venv 3.8 .venv38 "$py38" &
pids=($!)
if [ -n "$py310" ]; then
  make_venv 3.10 .venv310 "$py310" &
  pids+=($!)
fi
status=0
for pid in "${pids[@]}"; do wait "$pid" || status=$?; done
exit "$status"
