"""sim.processes.RosCore: a session's roscore leaves nothing behind but the logs asked for."""

from __future__ import annotations

import shutil
from pathlib import Path

from sim.processes import RosCore


def test_a_roscore_removes_its_own_temp_dir_unless_its_logs_are_kept() -> None:
    core = RosCore()
    assert (core.tmp / "log").is_dir() or any(core.tmp.iterdir())
    core.stop()
    assert not core.tmp.exists()
    kept = RosCore()
    try:
        kept.stop(keep_logs=True)
        assert any(kept.tmp.glob("roscore-*.log"))
    finally:
        shutil.rmtree(kept.tmp, ignore_errors=True)


def test_a_dir_that_was_given_is_left_alone_and_no_master_outlives_its_roscore(tmp_path) -> None:
    core = RosCore(tmp=tmp_path / "core")
    master_pid = core._master_pid()
    assert master_pid is not None
    core.stop()
    assert (tmp_path / "core").is_dir()
    assert gone(master_pid)


def gone(pid: int) -> bool:
    """No such process, or only its zombie (waiting for its parent to reap it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    except FileNotFoundError:
        return True
