"""sim.entry: how every command ends, and what it takes from rosrun and roslaunch."""

from __future__ import annotations

import pytest

from sim.entry import EXIT_BAD_INPUT, run_as_ros_command, without_ros_arguments


def test_rosrun_and_roslaunch_arguments_are_left_out_and_ours_kept_in_order():
    argv = ["--robot", "panda", "__name:=commander", "--goal=0.5,0.2", "__log:=/tmp/x.log", "/clock:=/sim_clock", "-v"]
    assert without_ros_arguments(argv) == ["--robot", "panda", "--goal=0.5,0.2", "-v"]
    assert without_ros_arguments([]) == []


def test_a_command_run_as_ros_runs_them_gets_its_own_arguments(tmp_path, monkeypatch, capsys):
    (tmp_path / "probe_command.py").write_text("def main(argv):\n    print('argv', argv)\n    return 7\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert run_as_ros_command("probe_command", ["--robot", "igt", "__name:=probe"]) == 7
    assert capsys.readouterr().out == "argv ['--robot', 'igt']\n"


def test_a_package_the_python_lacks_is_one_line_saying_how_to_get_it(tmp_path, monkeypatch, capsys):
    module = "import no_such_package_xyz.sub\n\n\ndef main(argv):\n    return 0\n"
    (tmp_path / "needs_yaml_lookalike.py").write_text(module)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert run_as_ros_command("needs_yaml_lookalike", []) == EXIT_BAD_INPUT
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("needs_yaml_lookalike: error: ") and "has no module 'no_such_package_xyz'" in line
    assert "rosdep install --from-paths src --ignore-src" in line and "pip3 install --user no_such_package_xyz" in line


def test_a_module_of_our_own_that_is_missing_is_a_bug_and_raises(tmp_path, monkeypatch):
    with pytest.raises(ModuleNotFoundError):
        run_as_ros_command("sim.no_such_module", [])
