#!/usr/bin/env bash
# The README's test command: set up (idempotently), then run the whole suite but the endpoint's integration tests,
# then the endpoint's tests on ROS Noetic's Python 3.8 with Debian's rospy. Extra args go to pytest (both runs).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$repo/launch_scripts/setup.sh"
"$repo/launch_scripts/setup_python38.sh"
cd "$repo"
# Lint and format first (pyproject.toml): a finding fails the run before any test starts.
.venv/bin/ruff check .
.venv/bin/ruff format --check .
# The endpoint's integration tests take minutes (the hostile-world ones most): they run once, on the oldest Python
# the endpoint supports, below. On this interpreter the endpoint still runs under every sim integration test (engine,
# commander, campaigns, description) and the catkin workspace tests (Debian's /usr/bin/python3).
# pytest exits 5 when it collected nothing: that must fail CI, and it does since we pass the code through.
.venv/bin/python -m pytest -q -p no:cacheprovider --ignore-glob="tests/integration/test_bridge_*.py" "$@" tests
echo "test.sh: the endpoint's tests on $(.venv38/bin/python --version)"
PYTHONPATH=/usr/lib/python3/dist-packages exec .venv38/bin/python -m pytest -q -p no:cacheprovider "$@" \
  tests/unit/bridge tests/integration/test_bridge_*.py
