"""What the VR page's server may serve (sim.study.views.vr.site): URLs name only the page's files, the npm packages'
parts the page imports and the robot's mesh folders; the URDF's meshes become those URLs; the settings carry the
scene."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sim.robots import find_ros_package
from sim.study.design.scene import load_scene, scene_robot
from sim.study.run.tracking import REST_S, announcement_from_json
from sim.study.views.errors import ViewError
from sim.study.views.vr.access import SECRET_PARAMETER
from sim.study.views.vr.site import WEB_DIR, Site, content_type, make_site, page_settings, pose_conditions_from


@pytest.fixture(scope="module")
def site() -> Site:
    scene = load_scene()
    robot = scene_robot(scene)
    return make_site(robot, scene, robot.urdf_path.read_text(), find_ros_package)


def test_every_mesh_of_the_urdf_is_a_url_under_a_served_folder(site: Site) -> None:
    import xml.etree.ElementTree as ET

    meshes = [element.get("filename", "") for element in ET.fromstring(site.urdf).iter("mesh")]
    assert meshes and all(name.startswith("robot/") for name in meshes)
    for name in meshes:  # urdf-loader asks for the filename relative to /robot.urdf
        served = site.file_for("/" + name)
        assert served is not None and served.is_file(), name
    assert {path.name for path in site.mesh_folders} == {"collision", "visual"}  # the Panda's two folders


@pytest.mark.parametrize(
    "path",
    [
        "/robot/0/../../../../etc/passwd",
        "/robot/0/..",
        "/robot/0/./link1.obj",
        "/robot/0//etc/passwd",
        "/robot/0/a\\..\\b",
        "/robot/99/link1.obj",
        "/robot/x/link1.obj",
        "/robot/0/",
        "/app/../site.py",
        "/app/certificate.py",
        "/vendor/three/package.json",
        "/vendor/three/build/../../../etc/passwd",
        "/vendor/iwer/build/iwer.module.js",  # only with the emulated headset
        "/app/emulation.js",
        "/app/probe.js",  # the tests' probe: only with the emulated headset
        "/app/frametime.js",  # only with --frame-time
        "/app/eslint.config.js",
        "/app/package.json",
        "/etc/passwd",
        "",
    ],
)
def test_nothing_else_on_the_machine_is_reachable(site: Site, path: str) -> None:
    assert site.file_for(path) is None


def test_the_page_its_files_and_the_libraries_it_imports(site: Site) -> None:
    assert site.file_for("/") == WEB_DIR / "index.html"
    assert site.file_for("/app/page.js") == WEB_DIR / "page.js"
    assert site.file_for("/vendor/three/build/three.module.js") == WEB_DIR / "node_modules/three/build/three.module.js"
    loader = site.file_for("/vendor/three/examples/jsm/loaders/OBJLoader.js")
    assert loader == WEB_DIR / "node_modules/three/examples/jsm/loaders/OBJLoader.js"
    emulated = Site(site.urdf, site.mesh_folders, site.settings, emulation=True)
    assert emulated.file_for("/vendor/iwer/build/iwer.module.js") == WEB_DIR / "node_modules/iwer/build/iwer.module.js"
    assert emulated.file_for("/app/probe.js") == WEB_DIR / "probe.js"
    assert emulated.file_for("/app/frametime.js") is None
    benched = Site(site.urdf, site.mesh_folders, site.settings, frame_time=True)
    assert benched.file_for("/app/frametime.js") == WEB_DIR / "frametime.js"
    assert benched.file_for("/app/probe.js") is None


def test_every_module_of_the_page_is_a_file_of_the_web_folder() -> None:
    from sim.study.views.vr.site import FRAME_TIME_FILES, PAGES

    listed = {name for page in PAGES.values() for name in page.files + page.emulation if name.endswith(".js")}
    assert listed | set(FRAME_TIME_FILES) == {path.name for path in WEB_DIR.glob("*.js")} - {"eslint.config.js"}
    for page in PAGES.values():
        assert all((WEB_DIR / name).is_file() for name in (page.entry, *page.files, *page.emulation))


def test_the_button_page_is_its_own_entry_with_the_vr_pages_ros_modules_and_nothing_of_the_robot() -> None:
    from sim.study.views.vr.site import make_button_site

    button = make_button_site()
    assert button.file_for("/") == WEB_DIR / "button.html" and button.file_for("/index.html") is None
    for name in ("button.js", "gamepad.js", "connection.js", "rostcp.js", "clock.js", "study.js", "button.css"):
        assert button.file_for(f"/app/{name}") == WEB_DIR / name
    for path in ("/app/page.js", "/app/scene.js", "/vendor/three/build/three.module.js", "/robot/0/link1.obj"):
        assert button.file_for(path) is None, path
    assert button.file_for("/app/gamepademulation.js") is None and button.file_for("/app/buttonprobe.js") is None
    emulated = make_button_site(emulation=True)
    assert emulated.instruments == ("gamepademulation.js", "buttonprobe.js")
    assert emulated.file_for("/app/gamepademulation.js") == WEB_DIR / "gamepademulation.js"
    assert emulated.file_for("/vendor/iwer/build/iwer.module.js") is None and emulated.file_for("/app/probe.js") is None
    settings = button.settings
    assert settings["topics"] == {
        "trial": ["/study/trial", "std_msgs/String"],
        "stop": ["/study/stop", "std_msgs/Header"],
        "page_clock": ["/study/page_clock", "std_msgs/String"],  # its clock's estimate, for the runner to judge
    }
    assert (
        settings["stop_source"] == "button" and settings["protocol"]["stop_sources"]["button"]["condition"] == "reality"
    )
    assert settings["key_parameter"] == SECRET_PARAMETER  # the part of the address address.js takes out


def test_the_settings_carry_the_scene_the_joints_and_the_topics(site: Site) -> None:
    settings = site.settings
    assert settings["seat"] == [0.55, -0.65, 0.45] and settings["hand"]["xyz"] == [0.55, 0.0, 0.0175]
    assert settings["robot"]["joint_names"][0] == "panda_joint1" and len(settings["robot"]["joint_names"]) == 7
    assert settings["topics"]["stop"] == ["/study/stop", "std_msgs/Header"]
    assert settings["topics"]["joint_states"] == ["/panda/joint_states", "sensor_msgs/JointState"]
    # the tracked body's, by the protocol's bodies, as the page advertises them
    assert {body: settings["topics"][body] for body in settings["protocol"]["poses"]["bodies"]} == {
        "head": ["/study/pose/head", "geometry_msgs/PoseStamped"],
        "left_hand": ["/study/pose/left_hand", "geometry_msgs/PoseStamped"],
        "right_hand": ["/study/pose/right_hand", "geometry_msgs/PoseStamped"],
    }
    assert settings["ros_path"] == "/ros" and settings["emulation"] is False
    assert settings["key_parameter"] == SECRET_PARAMETER  # the part of the address address.js takes out
    # the page's announcement of itself as the VR condition's pose source (alone, by default: in reality another
    # tracker is), as the runner reads one, its jitter not measured until the rest at the session's start
    assert settings["topics"]["tracking"] == ["/study/tracking", "std_msgs/String"]
    assert settings["topics"]["page_clock"] == ["/study/page_clock", "std_msgs/String"]  # its clock, to be judged
    said = announcement_from_json(json.dumps(settings["pose_source"]))
    assert (said["source"], said["conditions"], said["jitter_m"], said["rest_s"], said["calibration"]) == (
        "headset",
        ["vr"],
        {},
        None,
        None,
    )
    assert settings["rest"]["seconds"] == REST_S == 3.0  # the tracker relay's default
    assert "{left}" in " ".join(settings["rest"]["lines"])


def test_the_page_tracks_the_conditions_it_is_given() -> None:
    scene = load_scene()
    robot = scene_robot(scene)
    both = page_settings(robot, scene, ("vr", "reality"), 1.5)  # the headset worn in reality too (passthrough)
    assert both["pose_source"]["conditions"] == ["vr", "reality"] and both["rest"]["seconds"] == 1.5
    none = page_settings(robot, scene, ())  # another tracker tracks both: no poses, no rest
    assert none["pose_source"] is None and none["rest"] is None
    with pytest.raises(ViewError, match="'vr,vr'"):
        page_settings(robot, scene, ("vr", "vr"))
    # as `vr --pose-conditions` gives them
    assert pose_conditions_from("vr, reality") == ("vr", "reality") and pose_conditions_from("none") == ()
    with pytest.raises(ViewError, match="'vr,lab'"):
        pose_conditions_from("vr,lab")


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("page.js", "text/javascript"),
        ("link1.obj", "text/plain"),
        ("colors.png", "image/png"),
        ("x.bin", "application"),
    ],
)
def test_content_types(name: str, kind: str) -> None:
    assert content_type(Path(name)).startswith(kind)
