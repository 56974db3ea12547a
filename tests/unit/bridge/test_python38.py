"""bridge/ runs on ROS Noetic's Python 3.8: every module and package, and the catkin package's node script and
setup.py, compile and import there (no 3.9+ syntax, nor library API at import time). 3.9+ calls made only at run
time are caught by the bridge's tests, which launch_scripts/test.sh runs under 3.8 too."""

from __future__ import annotations

import os
import subprocess

from tests.rosenv import REPO

PYTHON38 = REPO / ".venv38" / "bin" / "python"
CATKIN_PACKAGE = REPO / "catkin_ws" / "src" / "ros_tcp_endpoint"


def test_every_bridge_module_imports_on_python_3_8() -> None:
    assert PYTHON38.exists(), "no .venv38 with Python 3.8: run launch_scripts/setup_ros_pythons.sh"
    modules = sorted(
        ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for parts in (path.relative_to(REPO).with_suffix("").parts for path in (REPO / "bridge").rglob("*.py"))
    )
    files = [str(CATKIN_PACKAGE / "scripts" / "default_server_endpoint.py"), str(CATKIN_PACKAGE / "setup.py")]
    code = (
        "import importlib, sys\n"
        "assert sys.version_info[:2] == (3, 8), sys.version\n"
        "modules, files = sys.argv[1].split(','), sys.argv[2].split(',')\n"
        "for name in modules: importlib.import_module(name)\n"
        "for path in files: compile(open(path).read(), path, 'exec')\n"
        "print(len(modules), len(files))\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{REPO}:/usr/lib/python3/dist-packages"}
    result = subprocess.run(
        [str(PYTHON38), "-c", code, ",".join(modules), ",".join(files)],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(len(modules)), str(len(files))]
