#!/usr/bin/env bash
# The README's test command: set up (idempotently), then run the whole suite, then the endpoint's own tests again
# on ROS Noetic's Python 3.8 with Debian's rospy. Extra args go to pytest (both runs).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$repo/launch_scripts/setup.sh"
"$repo/launch_scripts/setup_python38.sh"
cd "$repo"
# The endpoint's hostile-world tests (limits, deadlines, a failing master, chaos) take minutes: they run once, on the
# endpoint's own interpreter below, not on this one too.
ignore=()
for name in limits deadlines master chaos; do ignore+=("--ignore=tests/integration/test_bridge_$name.py"); done
# pytest exits 5 when it collected nothing: that must fail CI, and it does since we pass the code through.
.venv/bin/python -m pytest -q -p no:cacheprovider "${ignore[@]}" "$@" tests
echo "test.sh: the endpoint's tests on $(.venv38/bin/python --version)"
PYTHONPATH=/usr/lib/python3/dist-packages exec .venv38/bin/python -m pytest -q -p no:cacheprovider "$@" \
  tests/unit/test_bridge_*.py tests/integration/test_bridge_*.py
