"""The reality condition's stop button page (`python -m sim.study button`) in a real headless browser (Debian's
Chromium), with an emulated gamepad (loaded only with --emulate-gamepad: Chromium has no virtual one) as the
participant's foot pedal: over HTTPS with the page server's self-signed certificate, its WebSocket passed through to
the endpoint's, it stops the runner's approaches (--realtime) in a short reality session, stamped on the runner's
clock, and the CSV holds each press's source and its two latencies."""

from __future__ import annotations

import csv
import math
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

from measuring.browser import chromium, start_button_page
from sim.study.design.feasibility import Approaches
from sim.study.design.paths import ON_TOP
from sim.study.design.scene import load_scene, scene_robot
from sim.wire.contract import STEP_S
from tests.integration.sim_helpers import start_engine
from tests.integration.study_helpers import trial, write_plan
from tests.rosenv import PYTHON, EndpointProcess, ManagedProcess, RosCore, wait_for

PARTICIPANT = 6
PRESS_AFTER_MS = 600  # into the approach: the robot is well on its way (a slow approach takes some 6 s)
HOLD_MS = 150  # a foot on a pedal
CONTROLS = (0, 3)  # the buttons pressed in trials 1 and 2: any button counts
DELIVERY_S = 0.3  # a press from the page to the runner, on a quiet machine (as the VR page's test allows)
STALL_S = 90


def page_state(browser: Any) -> dict[str, Any] | None:
    """The page's state as its probe (window.buttonPage, loaded with --emulate-gamepad) tells it; None before the
    page has started."""
    return browser.execute_script("return window.buttonPage ? window.buttonPage.state() : null;")


# window.holdPressed(control): press button `control` and hold it for HOLD_MS, and on until the page has read it
# (the page reads the gamepad once an animation frame; a busy machine's headless browser may draw fewer than one frame
# in HOLD_MS, and a press released before any reading saw it is one that no page could see); its performance.now().
HOLD_PRESSED = (
    "window.holdPressed = (control) => { const page = window.buttonPage.page; const seen = page.presses.length;"
    " const at = window.emulatedGamepad.press(control);"
    " const hold = setInterval(() => {"
    f"  if (page.presses.length > seen && performance.now() - at >= {HOLD_MS}) {{"
    "   clearInterval(hold); window.emulatedGamepad.release(control); } }, 3);"
    " return at; };"
)


def press_while_moving(browser: Any, index: int, control: int) -> None:
    """Press button `control` PRESS_AFTER_MS after the page first shows trial `index` moving, then release it: timed
    by the page's own timers, off the animation frames that read the gamepad (a real pedal changes between frames),
    since a round trip through the browser's driver may take longer than the approach. Keeps when it was pressed
    (window.pressedAt[index]: performance.now(), ROS time by the page's clock, whether a press then would count)."""
    browser.execute_script(
        "const page = window.buttonPage.page; window.pressedAt = window.pressedAt || {};"
        "const watch = setInterval(() => { const status = page.participant.status;"
        f" if (!(status && status.index === {index} && status.phase === 'moving')) return;"
        " clearInterval(watch);"
        " setTimeout(() => {"
        f"  const at = window.holdPressed({control});"
        f"  window.pressedAt[{index}] = {{at, ros: page.connection.rosNow(), counts: page.counts}};"
        f" }}, {PRESS_AFTER_MS}); }}, 3);"
    )


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as rows:
        return list(csv.DictReader(rows))


def test_an_emulated_pedal_on_the_button_page_stops_the_runners_approaches(tmp_path: Path) -> None:
    core = RosCore()  # this test's own: the page's pings see its ROS time
    # ROS time is the runner's /clock: the endpoint answers the page's pings with it, so the page stamps its presses
    # on the runner's clock
    subprocess.run(["rosparam", "set", "/use_sim_time", "true"], env=core.env, check=True, timeout=30)
    endpoint = EndpointProcess(core.env, tmp_path, extra=["--websocket-port", "0"])
    processes: list[ManagedProcess] = [endpoint]
    out = tmp_path / "out"
    try:
        processes.append(start_engine(core, tmp_path, "panda", endpoint.port, "--no-auto-simulate"))
        page, url = start_button_page(endpoint.websocket_port, tmp_path)
        processes.append(page)
        assert url.startswith("https://localhost:")
        with chromium(tmp_path / "chromium", accept_insecure_certs=True, size="1200,900") as browser:
            browser.get(url)
            # it says so, in its next frame
            wait_for(lambda: (s := page_state(browser)) and "ROS: connected" in s["shown"], 60, "the page to connect")
            state = page_state(browser)
            assert state["connected"] and state["gamepads"] == [] and "No gamepad" in state["shown"]
            browser.execute_script("window.emulatedGamepad.connect();")
            wait_for(lambda: page_state(browser)["gamepads"] == ["Emulated foot pedal"], 10, "the page to see the pad")
            # before the session a press is shown, and not sent: no phase accepts it
            browser.execute_script(HOLD_PRESSED + "window.holdPressed(1);")
            wait_for(lambda: len(page_state(browser)["presses"]) == 1, 10, "the press before the session")
            assert page_state(browser)["presses"][0]["sent"] is False
            assert "would not count" in page_state(browser)["shown"]

            plan = write_plan(
                tmp_path / "plan.yaml",
                PARTICIPANT,
                "reality",
                [
                    trial(1, "reality", 2, "straight", ON_TOP, 0.1, "slow", 1),
                    trial(2, "reality", 2, "vertical", ON_TOP, 0.1, "slow", 1),
                ],
            )
            for index, control in zip((1, 2), CONTROLS):
                press_while_moving(browser, index, control)
            # go at once, and no preference is asked of anyone here: it is left empty after a few seconds
            runner = ManagedProcess(
                [PYTHON, "-m", "sim.study", "run", "--plan", str(plan), "--out", str(out), "--realtime"]
                + ["--auto-go", "--response-timeout", "3"],
                core.env,
                tmp_path,
                "runner",
            )
            processes.append(runner)
            seen: list[tuple[int, str]] = []
            last_progress = time.monotonic()
            while time.monotonic() - last_progress < STALL_S and runner.process.poll() is None:
                state = page_state(browser)
                if (state["index"], state["phase"]) not in seen:
                    seen.append((state["index"], state["phase"]))
                    last_progress = time.monotonic()
                if state["phase"] == "done":
                    break
                time.sleep(0.05)
            assert runner.wait(60) == 0, (seen, runner.output()[-3000:])
            state = page_state(browser)
            pressed_at = browser.execute_script("return window.pressedAt;")
            browser.save_screenshot(str(tmp_path / "button_page.png"))
    finally:
        for process in reversed(processes):
            process.stop()
        core.stop()

    presses = state["presses"][1:]
    assert [(p["index"], p["control"], p["sent"]) for p in presses] == [(1, 0, True), (2, 3, True)], state["presses"]
    assert all(pressed_at[str(index)]["counts"] for index in (1, 2))  # the page said a press would count
    rows = read_csv(out / f"participant_{PARTICIPANT:02d}.csv")
    scene = load_scene()
    with Approaches(scene_robot(scene), scene, STEP_S) as approaches:
        durations = [approaches.plan((path, ON_TOP, 0.1)).path.duration for path in ("straight", "vertical")]
    round_trip_s = state["clockRoundTripMs"] / 1000
    for row, press, duration in zip(rows, presses, durations):
        index = int(row["index"])
        assert row["pressed"] == "true" and row["press_source"] == "button", row
        motion_start, stamp = float(row["motion_start"]), press["stamp"]
        # Stamped on the runner's clock when the page read the pedal: the pedal's change plus its input delay, within
        # the approach, about PRESS_AFTER_MS into it
        when = pressed_at[str(index)]
        assert stamp == pytest.approx(when["ros"] + press["inputDelay"], abs=0.002), (stamp, when, press)
        assert motion_start < stamp < motion_start + duration, (stamp, motion_start, duration)
        # (less up to two steps: motion_start is the end of the step the runner has commanded, a step ahead of its
        # clock at most, and the page's clock is the endpoint's latest /clock, a step behind at most)
        assert stamp - motion_start > PRESS_AFTER_MS / 1000 - round_trip_s / 2 - 2 * STEP_S
        # The input delay the page measured is the CSV's (microseconds in the Header's seq), and a polling delay: at
        # least 0, at most the gap between the reading that saw the press and the one before, which did not
        input_delay = float(row["press_input_delay"])
        assert input_delay == pytest.approx(press["inputDelay"], abs=1e-6)
        assert 0 <= input_delay <= press["readingGap"] + 1e-6, (input_delay, press)
        # From the stamp to its arrival at the runner: the delivery (page, endpoint, runner), plus the error of the
        # page's clock offset, half its ping's round trip either way, and a step at most: the endpoint's ROS time is
        # the runner's latest /clock, which steps behind the runner's own
        arrival_delay = float(row["press_arrival_delay"])
        assert -round_trip_s / 2 <= arrival_delay < DELIVERY_S + round_trip_s / 2 + STEP_S, (arrival_delay, state)
        late = float(row["press_late"])
        assert float(row["press_time"]) == pytest.approx(stamp - motion_start + late, abs=0.01)
        assert math.isfinite(float(row["distance_at_press"])) and float(row["distance_at_rest"]) > 0.02
    print(
        f"button page: input delays {[p['inputDelay'] for p in presses]} s (readings apart "
        f"{[p['readingGap'] for p in presses]} s), arrival delays {[r['press_arrival_delay'] for r in rows]} s, "
        f"clock round trip {round_trip_s:.4f} s"
    )


pytestmark = [pytest.mark.lane("alone", on=("project",)), pytest.mark.timeout(300)]
