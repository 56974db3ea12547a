#!/usr/bin/env bash
# Idempotent: a Python 3.8 venv (ROS Noetic's Python) with the test tools only, for the endpoint's own tests.
# Debian's rospy comes from /usr/lib/python3/dist-packages through PYTHONPATH when the tests run (test.sh).
# The interpreter: $PYTHON38, else the newest $(pyenv root)/versions/3.8.*; none found is an error, never a skip.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo"

if [ ! -x .venv38/bin/python ]; then
  py38="${PYTHON38:-}"
  if [ -z "$py38" ]; then
    pyenv_root="$(pyenv root 2>/dev/null || echo "$HOME/.pyenv")"
    py38="$(ls -d "$pyenv_root"/versions/3.8.*/bin/python 2>/dev/null | sort -V | tail -n 1 || true)"
  fi
  if [ -z "$py38" ] || ! "$py38" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 8))' 2>/dev/null; then
    echo "setup_python38: no Python 3.8 found (set PYTHON38=/path/to/python3.8, or install one under" \
      "\$(pyenv root)/versions/3.8.*): the endpoint's tests on ROS Noetic's Python cannot run" >&2
    exit 1
  fi
  echo "setup_python38: creating .venv38 from $py38"
  "$py38" -m venv .venv38
fi
if [ ! -f .venv38/.setup_stamp ]; then
  echo "setup_python38: pip install pytest hypothesis pytest-timeout"
  .venv38/bin/python -m pip install -q --disable-pip-version-check pytest hypothesis pytest-timeout
  touch .venv38/.setup_stamp
fi
