#!/usr/bin/env bash
# The README's test command: set up (idempotently), lint, then the suite on three Pythons:
#   the project venv (Debian's 3.11): everything but what runs on Noetic's Python below;
#   .venv38 (ROS Noetic's 3.8, Debian's rospy): the endpoint's tests, the sim's unit tests and its ROS nodes;
#   .venv310 (Ubuntu 22.04's 3.10), when set-up found one: the sim's unit tests and the engine.
# Integration tests that are slow, or that prove a program runs on the old Pythons, run once: on 3.8, the oldest
# Python supported. On 3.11 the endpoint, engine and commander still run under every other integration test (the
# campaigns, the study, the catkin workspaces). Extra args go to pytest (every run).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# The ROS distros' venvs are made while setup.sh runs: neither writes what the other reads.
"$repo/launch_scripts/setup_ros_pythons.sh" &
ros_pythons=$!
"$repo/launch_scripts/setup.sh"
wait "$ros_pythons"
cd "$repo"
# One BLAS thread per test process: the lanes below already fill both cores, and OpenBLAS's extra threads spin while
# they wait for work, fighting every other process for the CPU. Measured beside two CPU burners: the 3.8 run of
# tests/unit/sim/study/power/test_sample_size.py (mixed models fitted in the test process) took over 150 s with OpenBLAS's default
# threads, 3 of its tests passing pytest's 300 s timeout in a full run, and 22 s with one thread.
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
# Lint and format first (pyproject.toml): a finding fails the run before any test starts.
.venv/bin/ruff check .
.venv/bin/ruff format --check .
# The same for the VR page's JavaScript and its node tests: ESLint and Prettier, at the versions of the page's
# package-lock.json (set-up's npm ci), their configurations beside it.
web=sim/study/views/vr/web
"$web/node_modules/.bin/eslint" --config "$web/eslint.config.js" "$web" tests/js
"$web/node_modules/.bin/prettier" --config "$web/.prettierrc.json" --check "$web/*.js" "tests/js/*.mjs"

python310=""
[ -x .venv310/bin/python ] && python310=.venv310/bin/python
status=0
run() {  # run PYTHON PYTEST_ARGS...: one pytest run; a failure is kept in $status. pytest exits 5 when it collected
  local python="$1"  # nothing: that fails like any other code.
  shift
  echo "test.sh: on $("$python" --version) ($python): $*" | cut -c1-200
  "$python" -m pytest -q -p no:cacheprovider "$@" || status=$?
}

# Two phases. Phase 1: the endpoint's integration tests on 3.8, which mostly wait on sockets, timers and the master,
# run beside what needs CPU but no timing (the unit tests on every Python, the study's and the processes' command
# lines, the description node). Phase 2: the tests that run a robot through ROS, one at a time and alone. Tried beside
# another suite (even at nice 10), the campaigns' bags lost messages: they record ~1000 messages a second per topic
# through rosbag record, whose queue (100 per topic) overflows when the recorder is starved of CPU; and a starved
# endpoint forwarded a lockstep step's /clock before its command (two topics, two connections).
beside_endpoint=(tests/integration/test_study_cli.py tests/integration/test_power_cli.py tests/integration/test_processes.py
  tests/integration/test_entry_points.py)
# Phase 2 on Noetic's Python: the engine stand-in, the physics node, the commander, a campaign's base case and a short
# simulated study (runner, participants, rosbag, report).
noetic_files=(tests/integration/test_engine.py tests/integration/test_physics_node.py
  tests/integration/test_commander.py)
noetic_tests=("tests/integration/test_trials.py::test_the_base_case_tracks_the_sweep_and_loses_nothing"
  "tests/integration/test_study.py::test_simulated_participants_run_the_study_and_the_analysis_recovers_their_biases")
alone=(--ignore-glob="tests/integration/test_bridge_*.py" --ignore=tests/integration/test_description.py)
for file in "${beside_endpoint[@]}" "${noetic_files[@]}"; do alone+=(--ignore="$file"); done
for test in "${noetic_tests[@]}"; do alone+=(--deselect="$test"); done

# The endpoint's lane (in the background, its output shown after the foreground's): its tests on 3.8, then the sim's
# unit tests on 3.10, which it has time for while the foreground runs the unit tests on 3.11 and 3.8.
endpoint_log="$(mktemp)"
trap 'rm -f "$endpoint_log"' EXIT
(
  lane_status=0
  echo "test.sh: on $(.venv38/bin/python --version) (.venv38/bin/python): tests/integration/test_bridge_*.py"
  .venv38/bin/python -m pytest -q -p no:cacheprovider "$@" tests/integration/test_bridge_*.py || lane_status=$?
  if [ -n "$python310" ]; then
    echo "test.sh: on $("$python310" --version) ($python310): tests/unit/sim"
    "$python310" -m pytest -q -p no:cacheprovider "$@" tests/unit/sim || lane_status=$?
  fi
  exit "$lane_status"
) >"$endpoint_log" 2>&1 &
endpoint_lane=$!
run .venv/bin/python "$@" tests/unit "${beside_endpoint[@]}"
run .venv38/bin/python "$@" tests/unit/bridge tests/unit/sim tests/integration/test_description.py
endpoint_status=0
wait "$endpoint_lane" || endpoint_status=$?
cat "$endpoint_log"
if [ "$endpoint_status" -ne 0 ]; then status=$endpoint_status; fi

run .venv/bin/python "${alone[@]}" "$@" tests/integration
run .venv38/bin/python "$@" "${noetic_files[@]}" "${noetic_tests[@]}"
if [ -n "$python310" ]; then run "$python310" "$@" tests/integration/test_engine.py; fi
if [ "$status" -ne 0 ]; then
  echo "test.sh: FAILED (a run above exited with $status)" >&2
  exit "$status"
fi
echo "test.sh: every run passed"
