"""The house rules that imports can break (docs/architecture.md), checked in fresh interpreters."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from sim.processes import PYTHON, REPO

ROS_MODULES = ("rospy", "roslaunch", "rosbag", "genpy")
TYPED_PACKAGES = ("bridge", "sim", "measuring", "bench")


def imported_after(module: str) -> set[str]:
    code = f"import sys, {module}; print(' '.join(sorted(sys.modules)))"
    result = subprocess.run([PYTHON, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return set(result.stdout.split())


# bridge/'s packages by concern, and whether each is pure (imports neither socket nor ROS); at the top, the server
# with the topic and service tables and what the whole endpoint shares (docs/architecture.md).
BRIDGE_PACKAGES = {
    "protocol": True,  # the ROS-TCP protocol, sans I/O
    "admission": True,  # who may come in
    "connection": False,  # one client's connection: sockets, threads
    "ros": False,  # the endpoint on the ROS graph: rospy, rosgraph, genpy
    "client": False,  # the Python client of the protocol: a socket
}
BRIDGE_TOP_MODULES = {
    "__main__",
    "server",
    "topics",
    "services",
    "bridged",
    "diagnostics",
    "settings",
    "config",
    "errors",
    "memory",
}
# The pure modules of the impure packages, each beside the I/O it feeds, and the pure modules at the top.
BRIDGE_PURE_MODULES = (
    "bridge.connection.queues",
    "bridge.ros.registry",
    "bridge.ros.peer_links",
    "bridge.ros.reachability",
    "bridge.memory",
    "bridge.diagnostics",
    "bridge.settings",
    "bridge.config",
    "bridge.errors",
)


def package_modules(package: str) -> list[str]:
    """Every module of a package under bridge/ (its __init__ as the package itself)."""
    folder = REPO / "bridge" / package
    return sorted(
        f"bridge.{package}" if path.stem == "__init__" else f"bridge.{package}.{path.stem}"
        for path in folder.glob("*.py")
    )


def test_every_bridge_package_and_top_module_is_listed() -> None:
    bridge = REPO / "bridge"
    assert {path.parent.name for path in bridge.glob("*/__init__.py")} == set(BRIDGE_PACKAGES)
    assert {path.stem for path in bridge.glob("*.py") if path.stem != "__init__"} == BRIDGE_TOP_MODULES
    assert not [path for path in bridge.glob("*/*/") if path.name != "__pycache__"], "one level of packages"


@pytest.mark.parametrize(
    "module",
    [
        *(module for package, pure in BRIDGE_PACKAGES.items() if pure for module in package_modules(package)),
        *BRIDGE_PURE_MODULES,
    ],
)
def test_pure_bridge_modules_import_neither_sockets_nor_ros(module: str) -> None:
    loaded = imported_after(module)
    assert not loaded & {"socket", *ROS_MODULES}, loaded & {"socket", *ROS_MODULES}


@pytest.mark.parametrize(
    "module",
    [
        "bridge.client",
        "bridge.client.connector",
        "sim.engine.stand_in",
        "sim.campaign.analysis",
        "sim.geometry.kinematics",
        "sim.engine.physics",
        "sim.robots",
        "sim.control.scenarios",
        "sim.study.design.paths",
        "sim.study.design.tool",
        "sim.study.run.protocol",
        "sim.study.questionnaires.scoring",
        "sim.study.analysis.summary",
        "sim.study.participants.simulated",
    ],
)
def test_the_client_and_the_engine_stand_in_import_no_ros(module: str) -> None:
    # Like Unity, the engine stand-in knows ROS only through the endpoint; it (de)serializes with rosbags.
    loaded = imported_after(module)
    assert not loaded & set(ROS_MODULES), loaded & set(ROS_MODULES)


# sim/'s parts from the bottom up: each may import from the layers below it and from itself, never from a layer above
# or a neighbour in its own layer (docs/architecture.md). The top layer is the commands kept under their names.
SIM_LAYERS = (
    ("errors", "entry", "cache"),
    ("cli_values", "processes"),
    ("launchers",),
    ("robots",),
    ("geometry",),
    ("wire",),
    ("engine", "control"),
    ("campaign", "study"),
    ("commander", "trials", "demo", "physics_node", "description_node"),
)


def sim_part(module: str) -> str:
    """The part of sim/ a module belongs to: its folder, or its own name for a module at the top."""
    return module.split(".")[1] if module.count(".") else module


def sim_imports(folder: Path) -> Iterator[tuple[str, str]]:
    """(importing module, imported sim module) for every import of sim by the modules under `folder`, even in
    functions."""
    for path in folder.rglob("*.py"):
        module = ".".join(path.relative_to(REPO).with_suffix("").parts)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "sim":
                targets = [node.module] if node.module != "sim" else [f"sim.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names if alias.name.split(".")[0] == "sim"]
            else:
                continue
            for target in targets:
                yield module, target


def upward_imports(
    folder: Path, layers: tuple[tuple[str, ...], ...], part_of: Callable[[str], str | None]
) -> list[str]:
    """The imports under `folder` from a part in the same layer or a layer above (`part_of` names a module's part;
    None: outside the layers)."""
    rank = {part: level for level, parts in enumerate(layers) for part in parts}
    wrong = []
    for module, target in sim_imports(folder):
        here, there = part_of(module), part_of(target)
        if there is not None and there != here and rank[there] >= rank[here]:
            wrong.append(f"{module} imports {target}")
    return wrong


def parts_on_disk(folder: Path) -> set[str]:
    return {path.parent.name for path in folder.glob("*/__init__.py")} | {
        path.stem for path in folder.glob("*.py") if path.stem != "__init__"
    }


def test_sim_parts_import_only_from_the_layers_below() -> None:
    assert parts_on_disk(REPO / "sim") == {part for parts in SIM_LAYERS for part in parts}, "every part has a layer"
    assert upward_imports(REPO / "sim", SIM_LAYERS, sim_part) == []


# sim.study's own parts, from the inputs to the sample size: a session is planned (design), run (run), answered by
# simulated participants or shown (participants, views) and analysed (analysis); power and the end-to-end simulation
# use all of those. The protocol that the runner and its answerers speak is in run/, below everyone who answers it.
# The questionnaires (instruments and their scoring) are below the design, which says when each is asked; the
# motion's measures (from tracked poses alone) below the runner, which takes them per approach. The safety checks (the
# limits a plan keeps, the braking on a press) between the design, which `check` verifies, and the runner.
STUDY_LAYERS = (
    ("errors",),
    ("checks",),
    ("questionnaires", "motion"),
    ("design",),
    ("safety",),
    ("run",),
    ("participants", "analysis", "views"),
    ("power", "simulation"),
    ("__main__",),
)


def study_part(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if parts[:2] == ["sim", "study"] and len(parts) > 2 else None


def test_the_study_parts_import_only_from_the_layers_below() -> None:
    study = REPO / "sim" / "study"
    assert parts_on_disk(study) == {part for parts in STUDY_LAYERS for part in parts}, "every part has a layer"
    assert upward_imports(study, STUDY_LAYERS, study_part) == []


def test_every_study_part_says_what_it_holds_and_has_its_own_error_type() -> None:
    study = REPO / "sim" / "study"
    for package in sorted(path.parent for path in study.glob("*/__init__.py")):
        assert ast.get_docstring(ast.parse((package / "__init__.py").read_text())), package
        errors = ast.parse((package / "errors.py").read_text()) if (package / "errors.py").is_file() else None
        assert errors is not None, f"{package} has no errors.py"
        classes = [node for node in errors.body if isinstance(node, ast.ClassDef)]
        assert len(classes) == 1, f"{package}/errors.py declares {len(classes)} error types"


# The last redesign of bridge/ brought every module to this size or under (docs/architecture.md: one room, one job).
BRIDGE_MODULE_MAX_LINES = 450


def test_no_bridge_module_is_over_its_size() -> None:
    sizes = {
        str(path.relative_to(REPO)): len(path.read_text().splitlines()) for path in (REPO / "bridge").rglob("*.py")
    }
    assert {name: lines for name, lines in sizes.items() if lines > BRIDGE_MODULE_MAX_LINES} == {}


# Where the house's code lives: no import circle may run through it, across its packages or within them.
HOUSE = ("bridge", "sim", "bench", "measuring")


def house_modules() -> dict[str, Path]:
    """Every module of the house by its dotted name (a package by its own name, for its __init__.py)."""
    modules = {}
    for package in HOUSE:
        for path in (REPO / package).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def imports_of(module: str, path: Path, modules: set[str]) -> set[str]:
    """The house's modules that `module` (at `path`) makes Python load: those it imports, anywhere in it, type-only
    ones (under `if TYPE_CHECKING:`) included, as a circle among them would be one the day they ran; and for each,
    the packages above it whose __init__.py runs first (not those above `module` itself: they are loading already)."""
    is_package = path.stem == "__init__"
    named: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            named.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package of `module`
                here = module.split(".") if is_package else module.split(".")[:-1]
                base = ".".join(here[: len(here) - node.level + 1] + ([base] if base else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                named.add(submodule if submodule in modules else base)
    own_packages = {".".join(module.split(".")[:i]) for i in range(1, module.count(".") + (1 if is_package else 0) + 1)}
    loaded = set()
    for name in named:
        parts = name.split(".")
        for i in range(1, len(parts) + 1):
            prefix = ".".join(parts[:i])
            if prefix in modules and prefix not in own_packages and prefix != module:
                loaded.add(prefix)
    return loaded


def house_import_graph() -> dict[str, set[str]]:
    modules = house_modules()
    return {module: imports_of(module, path, set(modules)) for module, path in modules.items()}


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every circle of imports in `graph` (module -> modules it imports), each once, as the path around it."""
    circles: list[list[str]] = []
    seen: set[frozenset[str]] = set()

    def walk(path: list[str]) -> None:
        for target in sorted(graph.get(path[-1], ())):
            if target == path[0] and frozenset(path) not in seen:
                seen.add(frozenset(path))
                circles.append([*path, target])
            elif target not in path and target > path[0]:  # each circle is found from its smallest module only
                walk([*path, target])

    for module in sorted(graph):
        walk([module])
    return circles


def test_import_circles_are_found() -> None:
    assert import_circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c", "a"]]
    assert import_circles({"a": {"b"}, "b": set()}) == []


def test_the_house_has_no_import_circle() -> None:
    """No module of bridge/, sim/, bench/ or measuring/ imports itself through others, type-only imports included."""
    circles = import_circles(house_import_graph())
    assert circles == [], "import circles: " + "; ".join(" -> ".join(circle) for circle in circles)


def test_the_import_graph_sees_type_only_imports_and_the_packages_loaded_on_the_way() -> None:
    graph = house_import_graph()
    assert "bridge.connection.session" in graph["bridge.admission.gate"]  # under TYPE_CHECKING
    assert "bridge.admission" in graph["bridge.settings"]  # the package runs before its module web_clients
    assert "bridge.protocol" not in graph["bridge.protocol.conversation"]  # its own package is loading already
    assert "bridge.protocol" in graph["bridge.server"]  # from bridge import protocol


def test_only_the_bridges_ros_modules_touch_rospy() -> None:
    """The endpoint's rospy code is in bridge/ros/, and only there; so is every import of genpy (and of the ROS
    tools it stands on)."""
    touching: dict[str, set[str]] = {}
    for path in (REPO / "bridge").rglob("*.py"):
        module = ".".join(path.relative_to(REPO).with_suffix("").parts)
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [alias.name for alias in node.names]
                if isinstance(node, ast.Import)
                else [node.module]
                if isinstance(node, ast.ImportFrom) and node.module
                else []
            )
            for name in names:
                touching.setdefault(name.split(".")[0], set()).add(module)
    assert touching["rospy"] | touching["rosgraph"] == {
        "bridge.ros.graph",
        "bridge.ros.master",
        "bridge.ros.network",
        "bridge.ros.peers",
        "bridge.ros.publisher",
        "bridge.ros.reader",
        "bridge.ros.service_proxy",
    }
    ros_tools = set().union(*(touching.get(name, set()) for name in ("genpy", "genmsg", "rospkg", "roslib")))
    assert ros_tools and all(module.startswith("bridge.ros.") for module in ros_tools), ros_tools


# What a ROS 1 install brings for Python (ROS's own packages): the endpoint may import these and the standard library.
ROS_PYTHON_PACKAGES = {"rospy", "rosgraph", "genpy", "genmsg", "rospkg", "roslib", "diagnostic_msgs", "std_msgs"}


def top_level_imports(package: str) -> dict[str, set[str]]:
    """Every top-level package that `package`'s modules import (even in functions; relative imports are its own),
    each with the files importing it."""
    imported: dict[str, set[str]] = {}
    for path in sorted((REPO / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                tops = [alias.name.split(".")[0] for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                tops = [node.module.split(".")[0]]
            else:
                continue
            for top in tops:
                imported.setdefault(top, set()).add(str(path.relative_to(REPO)))
    return imported


def foreign_imports(package: str, ours: set[str]) -> dict[str, list[str]]:
    """The top-level packages `package`'s modules import (every import, even in functions) that are neither the
    standard library nor `ours`, each with the files importing it."""
    return {
        top: sorted(files)
        for top, files in top_level_imports(package).items()
        if top not in sys.stdlib_module_names and top not in ours
    }


def test_the_bridge_needs_only_python_and_ros() -> None:
    """No pip dependency: a Noetic user runs the endpoint with what ROS installed. The one other package, the
    distribution's python3-wsproto, is optional (WebSocket clients only): imported by bridge.protocol.websocket alone,
    which the rest loads only when a WebSocket is asked for, and named by ros_tcp_endpoint's package.xml by a rosdep key
    the package defines (rosdistro has none)."""
    import xml.etree.ElementTree as ET

    import yaml

    foreign = foreign_imports("bridge", ROS_PYTHON_PACKAGES | {"bridge"})
    assert set(foreign) == {"wsproto"} and set(foreign["wsproto"]) == {"bridge/protocol/websocket.py"}, foreign
    loaded = imported_after("bridge.server") | imported_after("bridge.client") | imported_after("bridge.__main__")
    assert "wsproto" not in loaded
    package = REPO / "catkin_ws" / "src" / "ros_tcp_endpoint"
    depends = {element.text for element in ET.parse(package / "package.xml").getroot().iter("exec_depend")}
    assert "python3-wsproto" in depends
    assert yaml.safe_load((package / "rosdep.yaml").read_text())["python3-wsproto"]["ubuntu"] == ["python3-wsproto"]


# What sim imports beyond Python and ROS, and the rosdep key of vr_sim's package.xml that installs it.
SIM_ROSDEP_KEYS = {
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "statsmodels": "python3-statsmodels",  # the study's analysis
    "PIL": "python3-pil",  # the engine's --render pictures
    "h11": "python3-h11",  # the VR page's server
    "pybullet": "python3-pybullet-pip",
    "pybullet_data": "python3-pybullet-pip",
    "rosbags": "python3-rosbags-pip",  # defined by vr_sim's rosdep.yaml: rosdistro has no key for it
}
# Imported only by commands that are no ROS node: the campaign's progress bar and the study's live view (a missing
# one is named in one line, as any other, by sim.entry.run_as_ros_command and setup.py installs both).
SIM_OFF_NODE_PACKAGES = {"tqdm", "viser", "yourdfpy"}
ROS_MESSAGE_PACKAGES = {
    "geometry_msgs",
    "sensor_msgs",
    "trajectory_msgs",
    "rosgraph_msgs",
    "tf2_msgs",
    "std_msgs",
    "actionlib_msgs",  # control_msgs' action types, generated at run time (sim.wire.control_types)
    "actionlib",  # the stand-in's trajectory controller serves the action
}


def test_every_package_sim_imports_has_a_rosdep_key_in_vr_sim() -> None:
    import xml.etree.ElementTree as ET

    import yaml

    ours = ROS_PYTHON_PACKAGES | ROS_MESSAGE_PACKAGES | {"sim", "bridge"}
    foreign = foreign_imports("sim", ours)
    assert set(foreign) == set(SIM_ROSDEP_KEYS) | SIM_OFF_NODE_PACKAGES, foreign
    package = REPO / "catkin_ws" / "src" / "vr_sim"
    depends = {element.text for element in ET.parse(package / "package.xml").getroot().iter("exec_depend")}
    assert set(SIM_ROSDEP_KEYS.values()) | ROS_MESSAGE_PACKAGES <= depends
    own_keys = yaml.safe_load((package / "rosdep.yaml").read_text())
    assert own_keys["python3-rosbags-pip"]["ubuntu"]["pip"]["packages"] == ["rosbags"]


def test_sim_uses_no_bridge_internals_but_the_client() -> None:
    imported = set()
    for path in (REPO / "sim").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "bridge":
                imported.add(node.module)
            elif isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names if alias.name.split(".")[0] == "bridge")
    assert imported == {"bridge.client"}


# What the project ships stands apart from how it is measured: bridge/ and sim/ never import the measuring package,
# the benchmarks or the tests; measuring/ (which both tests/ and bench/ import) never imports either of them; and the
# benchmarks stand on their own, never importing the tests (what both use is in measuring/ or sim/).
NEVER_IMPORTED = {
    "bridge": {"measuring", "bench", "tests"},
    "sim": {"measuring", "bench", "tests"},
    "measuring": {"bench", "tests"},
    "bench": {"tests"},
}


@pytest.mark.parametrize("package", sorted(NEVER_IMPORTED))
def test_no_package_imports_what_measures_or_tests_it(package: str) -> None:
    imported = top_level_imports(package)
    wrong = {top: sorted(files) for top, files in imported.items() if top in NEVER_IMPORTED[package]}
    assert wrong == {}


def test_the_measuring_package_is_not_installed_for_users() -> None:
    """setup.py's packages and the catkin packages' are bridge and sim alone; measuring and bench stay in the
    repository (the tests and benchmarks import them from its root)."""
    setup = (REPO / "setup.py").read_text()
    assert 'find_packages(include=["bridge", "bridge.*", "sim", "sim.*"])' in setup
    for catkin_setup in sorted((REPO / "catkin_ws" / "src").glob("*/setup.py")):
        text = catkin_setup.read_text()
        assert "measuring" not in text and "bench" not in text, catkin_setup


def test_the_measuring_package_says_what_it_holds_and_has_its_own_error_type() -> None:
    measuring = REPO / "measuring"
    assert ast.get_docstring(ast.parse((measuring / "__init__.py").read_text()))
    classes = [node for node in ast.parse((measuring / "errors.py").read_text()).body if isinstance(node, ast.ClassDef)]
    assert [node.name for node in classes] == ["MeasuringError"]


def test_every_package_type_checks() -> None:
    """Fully typed: every def annotated, and mypy finds nothing (rospy, genpy and pybullet have no type
    information, hence Any there). One run for the four packages: each names its own errors, and the libraries'
    stubs they share (numpy's, scipy's) are read once, not once a package."""
    result = subprocess.run(
        [
            PYTHON,
            "-m",
            "mypy",
            "--ignore-missing-imports",
            "--follow-imports=silent",
            "--disallow-untyped-defs",
            "--cache-dir=/dev/null",
            *TYPED_PACKAGES,
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize(
    "package, root",
    [
        ("bridge", "bridge.errors.BridgeError"),
        ("sim", "sim.errors.SimError"),
        ("measuring", "measuring.errors.MeasuringError"),
    ],
)
def test_every_error_a_package_defines_is_under_its_root(package: str, root: str) -> None:
    """One error root per package: `except BridgeError` / `except SimError` catches every error raised on purpose
    (private control-flow signals, named with a leading underscore, aside)."""
    code = f"""
import importlib, inspect, pkgutil
import {package}
root_module, root_name = "{root}".rsplit(".", 1)
root = getattr(importlib.import_module(root_module), root_name)
outside = []
for info in pkgutil.walk_packages({package}.__path__, "{package}."):
    module = importlib.import_module(info.name)
    for name, value in vars(module).items():
        if inspect.isclass(value) and issubclass(value, BaseException) and value.__module__ == info.name \\
                and not name.startswith("_") and not issubclass(value, root):
            outside.append(f"{{info.name}}.{{name}}")
print(" ".join(outside))
"""
    result = subprocess.run([PYTHON, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == []


def test_the_repository_stands_on_its_own() -> None:
    """Docs, code and tests cite only what is in the repository: no notes from outside it."""
    tracked = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, timeout=60).stdout.split()
    outside = "../" + "shared"
    citing = [
        name for name in tracked if (REPO / name).is_file() and outside in (REPO / name).read_text(errors="ignore")
    ]
    assert citing == []
