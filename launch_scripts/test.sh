#!/usr/bin/env bash
# The README's test command: set up (idempotently), lint, then the suite's lanes on three Pythons (tests/lanes.py):
#   project: the project venv (Debian's 3.11);
#   noetic:  .venv38 (ROS Noetic's 3.8, Debian's rospy): the endpoint's tests, the sim's unit tests and its ROS nodes;
#   jammy:   .venv310 (Ubuntu 22.04's 3.10), when set-up found one: the sim's unit tests and the engine.
# Integration tests that are slow, or that prove a program runs on the old Pythons, run once: on 3.8, the oldest
# Python supported. On 3.11 the endpoint, engine and commander still run under every other integration test (the
# campaigns, the study, the catkin workspaces). Extra args go to pytest (every run).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# The ROS distros' venvs are made while setup.sh runs, and the lint below (neither writes what the other reads; the
# linters read none of the venvs, which .gitignore and ESLint's config leave out).
"$repo/launch_scripts/setup_ros_pythons.sh" &
ros_pythons=$!
"$repo/launch_scripts/setup.sh"
cd "$repo"
# One BLAS thread per test process: the lanes below already fill both cores, and OpenBLAS's extra threads spin while
# they wait for work, fighting every other process for the CPU. Measured beside two CPU burners: the 3.8 run of
# tests/unit/sim/study/power/test_sample_size.py (mixed models fitted in the test process) took over 150 s with OpenBLAS's default
# threads, 3 of its tests passing pytest's 300 s timeout in a full run, and 22 s with one thread.
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
# Bytecode, compiled once: set-up installs without byte-compiling, and with PYTHONDONTWRITEBYTECODE set (as our
# development machines set it) every process the suite starts (endpoints, engines, runners, pytest itself) compiled
# each module it imports afresh, NumPy's and SciPy's among them, and on 3.8 and 3.10 Debian's rospy too. Here each
# is compiled on its first import and kept in one folder of this checkout (git ignores it), not beside the sources
# in the venvs or Debian's dist-packages. A UR5-like arm's simulated study: 31.6 -> 26.7 CPU-s.
unset PYTHONDONTWRITEBYTECODE
export PYTHONPYCACHEPREFIX="$repo/.pycache"
# The study's cache (self-contact verdicts, scenes proposed for other arms) is this run's own: every run computes
# them afresh, once, and the user's ~/.cache/vr_sim is left alone.
VR_SIM_CACHE="$(mktemp -d)"
export VR_SIM_CACHE
# Lint and format first (pyproject.toml): a finding fails the run before any test starts (once the venvs' set-up
# has ended, not left running behind the failed run).
web=sim/study/views/vr/web
lint() {
  .venv/bin/ruff check . &&
    .venv/bin/ruff format --check . &&
    # The same for the VR page's JavaScript and its node tests: ESLint and Prettier, at the versions of the page's
    # package-lock.json (set-up's npm ci), their configurations beside it.
    "$web/node_modules/.bin/eslint" --config "$web/eslint.config.js" "$web" tests/js &&
    "$web/node_modules/.bin/prettier" --config "$web/.prettierrc.json" --check "$web/*.js" "tests/js/*.mjs"
}
lint_status=0
lint || lint_status=$?
wait "$ros_pythons"
if [ "$lint_status" -ne 0 ]; then exit "$lint_status"; fi
echo "test.sh: set-up and the lint took ${SECONDS} s"

python310=""
[ -x .venv310/bin/python ] && python310=.venv310/bin/python
status=0
run() {  # run PYTHON ROLE LANE... -- PYTEST_ARGS...: the tests of those lanes that run on that Python (tests/lanes.py);
  local python="$1" role="$2" lanes=()  # a failure is kept in $status. pytest exits 5 when it collected nothing:
  shift 2                                # that fails like any other code.
  while [ "$1" != "--" ]; do lanes+=(--lane "$1"); shift; done
  shift
  # (at $SECONDS since test.sh started: each lane's start, for the phases' times in README)
  echo "test.sh: at ${SECONDS} s, on $("$python" --version) ($python): ${lanes[*]} $*" | cut -c1-200
  # --durations: each run ends with its slowest tests, where a lane's time goes (before any extra args: theirs win)
  "$python" -m pytest -q -p no:cacheprovider --durations=25 --on "$role" "${lanes[@]}" "$@" tests || status=$?
}
# Each test file names its lane and the Pythons that run it (pytestmark = pytest.mark.lane(...); unit tests by their
# folder), and tests/unit/test_lanes.py holds that every file has one. The alone lane holds the tests that run a robot
# through ROS on wall time or record bags: the campaigns' lockstep records 250 messages a second per topic through
# rosbag record, whose queue (100 per topic) overflows when the recorder is starved of CPU; a starved endpoint forwarded
# a lockstep step's /clock before its command (two topics, two connections); a starved driver's joint states go stale
# and the reality condition's runner rightly stops the arm. Beside another suite at the same priority (and even at nice
# 10) they failed so. So the alone lanes run one after another at the normal priority, and every other lane runs at the
# same time under SCHED_IDLE (chrt --idle): the kernel gives those only the CPU that the alone lanes leave (they use
# about one core of two, waiting on the clock and on each other's messages), and takes it back at once when an alone
# test's process wakes. The other lanes need CPU but no timing of their own against the alone lanes: the unit lanes, the
# beside lanes (the study's and the processes' command lines, the benches' smoke tests, the arms' simulated studies),
# and the endpoint's lane, whose tests mostly wait on sockets and timers. The endpoint's tests that time it beside CPU
# burners of their own (the call bursts, each call's answer within 1 s of its deadline) are in 3.8's alone lane: under
# SCHED_IDLE they shared the little the alone lanes left with their burners, and failed.

# Under SCHED_IDLE, in the background, their output shown after the alone lanes': the endpoint's lane on 3.8, then
# the beside lane on 3.8, with the unit lanes beside them, one after the other: 3.10's, 3.8's, then the project's
# (the endpoint's tests use about half a core). The project's Python runs its beside lane all along (the benches'
# smoke tests, the study's command lines and its arms are there; the power tests' error rates and the reality
# condition's refusals are on 3.8 so that the two end about together). When 3.8's beside lane went after the
# project's unit lane, it was the last lane to end, half a minute after the others.
idle_log="$(mktemp)"
endpoint_log="$(mktemp)"
units_log="$(mktemp)"
realtime_log="$(mktemp)"
trap 'rm -rf "$idle_log" "$endpoint_log" "$units_log" "$realtime_log" "$VR_SIM_CACHE"' EXIT
(
  chrt --idle --pid 0 "$BASHPID"  # this subshell, and every process it starts, inherit the policy
  status=0
  (
    status=0
    (
      if [ -n "$python310" ]; then run "$python310" jammy unit -- "$@"; fi
      run .venv38/bin/python noetic unit -- "$@"
      run .venv/bin/python project unit -- "$@"
      exit "$status"
    ) >"$units_log" 2>&1 &
    units=$!
    run .venv38/bin/python noetic endpoint -- "$@"
    run .venv38/bin/python noetic beside -- "$@"
    wait "$units" || status=$?
    cat "$units_log"
    exit "$status"
  ) >"$endpoint_log" 2>&1 &
  endpoint_lane=$!
  run .venv/bin/python project beside -- "$@"
  wait "$endpoint_lane" || status=$?
  cat "$endpoint_log"
  exit "$status"
) >"$idle_log" 2>&1 &
idle_lanes=$!

# The realtime lane drives a real arm's stand-in on wall time (the reality condition, its faults, the trajectory
# controller): about half a core, mostly asleep, but a process that wakes must run within milliseconds, or its joint
# states go stale and the runner rightly brakes the arm. At the normal priority beside other work (even at nice -5)
# it failed so. Under SCHED_RR (chrt --rr), as a robot's control software runs, the kernel runs it before any
# normal or idle process whenever it wakes, so it runs beside the alone lanes (3.11's, then 3.8's and 3.10's)
# instead of after them. chrt --rr needs root (or CAP_SYS_NICE); without it, the lane runs after them.
realtime_lane=""
if chrt --rr 1 true 2>/dev/null; then
  (
    chrt --rr --pid 1 "$BASHPID"
    run .venv/bin/python project realtime -- "$@"
    exit "$status"
  ) >"$realtime_log" 2>&1 &
  realtime_lane=$!
fi

# The alone lanes one after another: 3.11's (the study's lockstep sessions), then 3.8's and 3.10's (the engine, the
# physics node and the commander on wall time, the slow link).
run .venv/bin/python project alone -- "$@"
run .venv38/bin/python noetic alone -- "$@"
if [ -n "$python310" ]; then run "$python310" jammy alone -- "$@"; fi
if [ -n "$realtime_lane" ]; then
  wait "$realtime_lane" || status=$?
  cat "$realtime_log"
else
  echo "test.sh: chrt --rr is not allowed here: the realtime lane runs after the alone lanes"
  run .venv/bin/python project realtime -- "$@"
fi
# Once the realtime lane has ended: the quiet lanes, whose bounds the realtime lane beside them broke (the catkin
# demo's tracking, paced by the wall clock, 0.062 % against 0.05; the emulated Quest's page clock, its best round
# trip 69 ms against 40; the base case's campaign, paced by the wall clock), with the browsers' tests, whose
# software rendering takes about a core: beside the realtime lane they left the idle lanes nothing for seconds (an
# endpoint's test waited over 10 s for its own endpoint to log a ping). 3.8's holds the base case's campaign.
run .venv/bin/python project quiet -- "$@"
run .venv38/bin/python noetic quiet -- "$@"
idle_status=0
wait "$idle_lanes" || idle_status=$?
cat "$idle_log"
if [ "$idle_status" -ne 0 ]; then status=$idle_status; fi
if [ "$status" -ne 0 ]; then
  echo "test.sh: FAILED (a run above exited with $status), in ${SECONDS} s" >&2
  exit "$status"
fi
echo "test.sh: every run passed, in ${SECONDS} s"
