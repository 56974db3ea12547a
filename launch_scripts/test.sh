#!/usr/bin/env bash
# The README's test command: set up (idempotently), then run the whole suite. Extra args go to pytest.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$repo/launch_scripts/setup.sh"
cd "$repo"
# pytest exits 5 when it collected nothing: that must fail CI, and it does since we pass the code through.
exec .venv/bin/python -m pytest -q -p no:cacheprovider "$@" tests
