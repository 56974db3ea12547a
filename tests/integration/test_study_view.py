"""The experimenter's live 3-D view (sim.study.views.live) in a real headless browser (Debian's Chromium, WebGL in
software): the page shows the scene before a trial, and the planned path, the trail and the stop after one, as the
screenshots' pixels tell."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from PIL import Image

from measuring.browser import chromium
from sim.launchers import LiveView, Participant, Runner, finish, start, wait_ready
from sim.processes import PYTHON, REPO, plain_env
from sim.study.design.paths import ON_TOP
from sim.study.views.live import COLOURS
from tests.integration import pixels
from tests.integration.sim_helpers import start_engine
from tests.integration.study_helpers import trial, write_plan
from tests.rosenv import free_port, wait_for
from tests.study_arms import study_arm


@pytest.fixture(scope="module")
def shared_browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """One headless Chromium for the module's tests: a browser's start is some seconds of the machine's two cores."""
    with chromium(tmp_path_factory.mktemp("chromium")) as driver:
        yield driver


@pytest.fixture
def browser(shared_browser: Any) -> Iterator[Any]:
    """The shared browser, on a blank page after the test: each test opens its own view's address (a server of its
    own, on a port of its own) and reads only what that page shows, and the page it leaves stops drawing before the
    next test starts."""
    try:
        yield shared_browser
    finally:
        shared_browser.get("about:blank")


def settled_screenshot(driver: Any, path: Path, listed: str, timeout: float = 60.0) -> np.ndarray:
    """Once the page's scene tree lists `listed` and two screenshots in a row are the same picture (the scene has
    faded in and stopped changing), the last of them. Screenshots are half a second apart: a frame of software
    WebGL takes a while, and there is nothing to wait on but the picture itself."""
    previous: list[np.ndarray] = []

    def steady() -> bool:
        if listed not in driver.find_element("tag name", "body").text:
            return False
        driver.save_screenshot(str(path))
        image = np.asarray(Image.open(path).convert("RGB")).astype(int)
        same = bool(previous) and int(np.abs(image - previous[0]).max()) < 8
        previous[:] = [image]
        return same

    wait_for(steady, timeout, f"the page to settle with {listed}", interval=0.5)
    return previous[0]


def pixels_like(image: np.ndarray, colour: tuple[int, int, int], tolerance: int = 60) -> int:
    """Pixels of about that colour in the 3-D scene: between the notice on the left and viser's panel on the right,
    whose buttons are blue."""
    return pixels.pixels_like(image[:, 330:850], colour, tolerance)


# The bundled scene's Panda in lockstep; an arm from its URDF alone (the scene proposed for it), run in real time
@pytest.mark.parametrize(("arm", "realtime"), [("panda", False), ("small_gripper_arm", True)])
def test_the_live_view_shows_the_scene_the_plan_the_trail_and_the_stop(
    roscore, endpoint, browser, tmp_path: Path, arm: str, realtime: bool
) -> None:
    robot = "panda" if arm == "panda" else str(study_arm(tmp_path / "arms", arm))
    robot_args: tuple[str, ...] = ()  # the study's processes: the bundled scene's robot
    if arm != "panda":  # the scene proposed for the arm, once, before the processes start (each would propose it)
        scene = tmp_path / "scene.yaml"
        proposed = subprocess.run(
            [PYTHON, "-m", "sim.study", "scene", "--robot", robot, "--out", str(scene)],
            cwd=REPO,
            env=plain_env(),
            capture_output=True,
            text=True,
            timeout=240,
        )
        assert proposed.returncode == 0, proposed.stderr[-2000:]
        assert yaml.safe_load(scene.read_text())["approach_scale"] == 1.0  # a six-joint arm that fits the paths whole
        robot_args = ("--robot", robot, "--scene", str(scene))
    engine = start_engine(roscore, tmp_path, robot, endpoint.port, "--no-auto-simulate")
    http = free_port()
    live_view, simulated = LiveView(endpoint.port, http, robot_args), Participant(5, 2, endpoint.port, robot_args)
    view = start(live_view, plain_env(), tmp_path, "view", wait=False)
    participant = start(simulated, plain_env(), tmp_path, "participant", wait=False)
    try:
        wait_ready(view, live_view)
        wait_ready(participant, simulated)
        browser.get(f"http://127.0.0.1:{http}")
        before = settled_screenshot(browser, tmp_path / "before.png", "/hand")
        assert pixels_like(before, COLOURS["hand"]) > 300 and pixels_like(before, COLOURS["table"]) > 20_000
        for part in ("path", "trail", "stop"):
            assert pixels_like(before, COLOURS[part]) < 20, part
        plan = write_plan(tmp_path / "plan.yaml", 5, "vr", [trial(1, "vr", 2, "straight", ON_TOP, 0.3, "fast", 1)])
        session = Runner(plan, tmp_path / "out", robot_args, realtime=realtime, record=False)
        runner = start(session, roscore.env, tmp_path, "runner")
        finish(runner, 120)
        after = settled_screenshot(browser, tmp_path / "after.png", "/stop_distance")
        counts = {part: pixels_like(after, COLOURS[part]) for part in ("hand", "path", "trail", "stop")}
        # the trail runs along the path it followed, the lines sharing pixels: a short approach leaves few of its own
        assert counts["hand"] > 300 and counts["path"] > 200 and counts["trail"] > 20 and counts["stop"] > 20, counts
        assert np.abs(after - before).max(axis=2).astype(bool).sum() > 5_000  # the robot moved on the page
    finally:
        participant.stop()
        view.stop()
        engine.stop()


# The quiet lane: its Chromium renders in software, about a core (tests/lanes.py)
pytestmark = [pytest.mark.lane("quiet", on=("project",)), pytest.mark.timeout(300)]
