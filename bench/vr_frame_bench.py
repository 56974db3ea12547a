"""Benchmark of the VR page's frame time (`python -m sim.study vr`): how long the page takes to draw one frame of
the immersive session with the Panda's meshes, beside the 72-90 Hz a headset needs (13.9-11.1 ms per frame).

    .venv/bin/python -m bench.vr_frame_bench [--seconds 20] [--size 800,600] [--only rendered|submitted]

Method. Its own roscore, an endpoint with its WebSocket port, and the page's server with the emulated Meta Quest 3
(IWER, --emulate-headset, which loads the tests' probe window.vrPage too) and the frame-time instrument (--frame-time,
window.vrFrameTime), opened in Debian's headless Chromium. The robot moves the whole time: this process publishes the
Panda's joint states at 100 Hz through the endpoint's TCP port (each joint on a slow sine), and the page applies the
latest at every frame. Once in the session, the page's own figures are read:
- the work of each frame: applying the joints, reading the controllers, the panel, and rendering both eyes;
- pass `rendered` sets the instrument's waitForRendering, so each frame waits for its rendering to end (it reads one
  pixel back) and the figure includes the rendering itself; pass `submitted` does not wait, so it is what the page's
  JavaScript and three.js cost before the GPU works;
- the interval between frames, as the emulated headset's frame loop scheduled them.

Here the rendering is SwiftShader, WebGL in software on this machine's CPU cores, into the emulated headset's
framebuffer (the page's canvas: IWER renders both eyes side by side into it). A headset's GPU renders far faster:
`rendered` is an upper bound for this scene, `submitted` is the part a headset's GPU cannot take over. Every loop
is bounded in time; every process is stopped by PID.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from bridge.client import TcpClient
from measuring.browser import chromium, start_vr_page
from measuring.stats import percentile
from sim.processes import EndpointProcess, ManagedProcess, RosCore, wait_for
from sim.study.design.scene import load_scene, scene_robot
from sim.wire.rosmsgs import JOINT_STATE, encode_joint_state

HEADSET_RATES_HZ = (72, 90)
PUBLISH_HZ = 100.0
PASSES = ("rendered", "submitted")  # the frame's work with its rendering waited for, and without
SETTLE_S = 3.0  # after entering the session, before the frames counted (shaders compiled, meshes uploaded)


def publish_joint_states(port: int, stop: threading.Event) -> None:
    """The Panda's joints on slow sines around its home, at PUBLISH_HZ, until `stop` (at most 10 minutes)."""
    robot = scene_robot(load_scene())
    home = np.asarray(robot.home, dtype=float)
    client = TcpClient("127.0.0.1", port)
    client.register_publisher(robot.joint_states_topic, JOINT_STATE)
    client.connect()
    started = time.monotonic()
    seq = 0
    try:
        while not stop.is_set() and time.monotonic() - started < 600:
            t = time.monotonic() - started
            phases = np.arange(robot.dof)
            positions = home + 0.3 * np.sin(0.5 * t + phases)
            velocities = 0.15 * np.cos(0.5 * t + phases)
            client.publish(
                robot.joint_states_topic,
                encode_joint_state(seq, time.time(), robot.joint_names, positions, velocities, np.zeros(robot.dof)),
            )
            seq += 1
            stop.wait(max(0.0, started + seq / PUBLISH_HZ - time.monotonic()))
    finally:
        client.close()


def page_figures(browser: Any) -> dict[str, Any]:
    return browser.execute_script(
        "const s = window.vrPage.state(); const t = window.vrFrameTime;"
        "const r = window.vrPage.page.view.renderer; const layer = r.xr.getSession()?.renderState.baseLayer;"
        "return {work: t.work.slice(), intervals: t.intervals.slice(), frames: s.frames, jointStates: s.jointStates,"
        " triangles: r.info.render.triangles,"
        " framebuffer: layer ? [layer.framebufferWidth, layer.framebufferHeight] : null, error: s.error};"
    )


def measure(browser: Any, url: str, wait_for_rendering: bool, seconds: float) -> dict[str, Any]:
    """Load the page at `url`, enter the session, and read its figures over `seconds` (after SETTLE_S)."""
    browser.get(url)
    wait_for(
        lambda: browser.execute_script(
            "const s = window.vrPage ? window.vrPage.state() : null;"
            "return !!s && !!window.vrFrameTime && s.meshes && s.connected && s.enterable;"
        ),
        120,
        "the page to load the Panda's meshes and connect",
    )
    browser.execute_script(f"window.vrFrameTime.waitForRendering = {str(wait_for_rendering).lower()};")
    browser.find_element("id", "enter").click()
    wait_for(lambda: browser.execute_script("return window.vrPage.state().inSession;"), 60, "the immersive session")
    time.sleep(SETTLE_S)
    before = page_figures(browser)
    time.sleep(seconds)
    after = page_figures(browser)
    frames = after["frames"] - before["frames"]
    return {
        **after,
        "frames_counted": frames,
        "work": after["work"][-frames:] if frames > 0 else [],
        "intervals": after["intervals"][-frames:] if frames > 0 else [],
        "joint_states_per_s": (after["jointStates"] - before["jointStates"]) / seconds,
        "seconds": seconds,
    }


def report(name: str, figures: dict[str, Any]) -> str:
    work, intervals = figures["work"], figures["intervals"]
    median = statistics.median(work) if work else math.nan
    p95 = percentile(work, 95) if work else math.nan
    within = {hz: sum(1 for w in work if w <= 1000.0 / hz) / len(work) if work else math.nan for hz in HEADSET_RATES_HZ}
    return (
        f"| {name} | {len(work)} | {median:.2f} | {p95:.2f} | {max(work, default=math.nan):.2f} | "
        f"{1000.0 / median:.0f} | {100 * within[72]:.0f} % | {100 * within[90]:.0f} % | "
        f"{statistics.median(intervals) if intervals else math.nan:.2f} | {figures['joint_states_per_s']:.0f} |"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="frames counted per pass (default 20 s)")
    parser.add_argument("--size", default="800,600", help="the browser window (default 800,600)")
    parser.add_argument("--only", choices=PASSES, help="one pass only (default both)")
    args = parser.parse_args()
    if not 1 <= args.seconds <= 300:
        parser.error("--seconds must be between 1 and 300")

    tmp = Path(tempfile.mkdtemp(prefix="vr-frame-bench-"))
    core = RosCore()
    processes: list[ManagedProcess] = []
    stop = threading.Event()
    results: dict[str, dict[str, Any]] = {}
    try:
        endpoint = EndpointProcess(core.env, tmp, extra=["--websocket-port", "0"])
        processes.append(endpoint)
        assert endpoint.websocket_port is not None  # asked for with --websocket-port
        vr, url = start_vr_page(endpoint.websocket_port, tmp, frame_time=True)
        processes.append(vr)
        publisher = threading.Thread(target=publish_joint_states, args=(endpoint.port, stop), daemon=True)
        publisher.start()
        for name in (args.only,) if args.only else PASSES:
            wait_for_rendering = name == "rendered"
            with chromium(tmp / f"chromium-{name}", accept_insecure_certs=True, size=args.size) as browser:
                print(f"vr_frame_bench: pass {name} ({args.seconds:g} s) ...", file=sys.stderr, flush=True)
                results[name] = measure(browser, url, wait_for_rendering, args.seconds)
    finally:
        stop.set()
        for process in reversed(processes):
            process.stop()
        core.stop()
        shutil.rmtree(tmp, ignore_errors=True)  # the browsers' profiles, the certificate, the logs

    first = next(iter(results.values()))
    width, height = first["framebuffer"] or (0, 0)
    print(
        f"VR page frame time: the Panda with its meshes ({first['triangles']} triangles a frame, both eyes), "
        f"the emulated Quest 3's framebuffer {width}x{height}, WebGL in software (SwiftShader), "
        f"headless Chromium, window {args.size}; joint states published at {PUBLISH_HZ:.0f} Hz"
    )
    print()
    print(
        "| pass | frames | work median (ms) | p95 | max | rate the work allows (Hz) | frames within 72 Hz (13.9 ms) "
        "| within 90 Hz (11.1 ms) | frame interval median (ms) | joint states received /s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, figures in results.items():
        print(report(name, figures))
    for name, figures in results.items():
        if figures["error"]:
            print(f"the page reported, in pass {name}: {figures['error']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
