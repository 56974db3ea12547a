#!/usr/bin/env bash
# The main job: set up, then run the demo end to end on embedded defaults (own roscore on a free port).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$repo/launch_scripts/setup.sh"
cd "$repo"
exec .venv/bin/python -m sim.demo "$@"
