"""Benchmark of the VR page's frame time (`python -m sim.study vr`): how long the page takes to draw one frame of
the immersive session with the Panda's meshes, beside the 72-90 Hz a headset needs (13.9-11.1 ms per frame); and how
late a press of the trigger reaches ROS.

    .venv/bin/python -m bench.vr_frame_bench [--seconds 20] [--size 800,600] [--only rendered|submitted]
                                             [--presses 20]

Each pass measures the frames with the tracked body's poses off and on (the frame loop's switch, set through the
instrument), `--seconds` each, in alternating slices in one session, and prints both and their difference. After the
last pass, in its session, the trigger is pressed `--presses` times (see "Presses" below).

Method. Its own roscore, an endpoint with its WebSocket port, and the page's server with the emulated Meta Quest 3
(IWER, --emulate-headset, which loads the tests' probe window.vrPage too) and the frame-time instrument (--frame-time,
window.vrFrameTime), opened in Debian's headless Chromium. The robot moves the whole time: this process publishes the
Panda's joint states at 100 Hz through the endpoint's TCP port (each joint on a slow sine), and the page applies the
latest at every frame. It also publishes a trial's status (latched, phase moving): the page is in a trial, and sends
the participant's tracked body (the emulated headset's head and two hands, three PoseStamped a frame) while its poses
are on; this process subscribes to them through the endpoint, to count what reaches ROS. Once in the session, the
page's own figures are read:
- the work of each frame: applying the joints, reading the controllers, the panel, and rendering both eyes;
- pass `rendered` sets the instrument's waitForRendering, so each frame waits for its rendering to end (it reads one
  pixel back) and the figure includes the rendering itself; pass `submitted` does not wait, so it is what the page's
  JavaScript and three.js cost before the GPU works;
- the interval between frames, as the emulated headset's frame loop scheduled them;
- poses off and on: the instrument switches the frame loop's poses between two frames and records, per frame, whether
  they were on and how many it sent. Off and on alternate in SLICES slices of each, so that a change in what else
  the machine runs falls on both; the difference of their medians is what the poses cost, beside the spread of one
  mode's slices, the noise of the measure. As that noise is far larger than the poses' part, the instrument also times
  the part itself in each frame (reading the bodies, encoding and sending them): its mean, as Chromium's clock is
  coarse (0.1 ms steps, with jitter, unless the page is cross-origin isolated), and its largest.

Presses. The page's stop, as a participant gives it in a trial's approach: for each press this process publishes a
new trial's status in phase moving (its motion starting now), waits until the page shows it, and presses the emulated
right controller's trigger for 150 ms. The page stamps the press on ROS time by its clock offset (its pings of the
endpoint; ROS time is the machine's clock here, no /clock runs) and publishes it on the stop's topic, with its input
delay in the Header's seq, as in a session. This process subscribes to that topic through the endpoint and takes the
press's arrival on the same clock. Per press: the input delay (the page's, from the frame that read the trigger to the
stamp) and the delivery (the stamp to the arrival here: the page's send, the page server's relay, the endpoint, ROS,
and the endpoint again to this process's TCP client, one leg more than the runner's; the page's clock offset adds its
error, at most half its ping's round trip, printed beside). The study runner records the same two figures of each
press (press_input_delay, press_arrival_delay) and applies the press at its arrival (press_late): the delivery is what
a stop loses on its way, at the robot's speed.

Here the rendering is SwiftShader, WebGL in software on this machine's CPU cores, into the emulated headset's
framebuffer (the page's canvas: IWER renders both eyes side by side into it). A headset's GPU renders far faster:
`rendered` is an upper bound for this scene, `submitted` is the part a headset's GPU cannot take over. Every loop
is bounded in time; every process is stopped by PID.
"""

from __future__ import annotations

import argparse
import math
import queue
import shutil
import statistics
import sys
import tempfile
import threading
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from bridge.client import TcpClient
from measuring.browser import chromium, launch_secrets, start_vr_page
from measuring.stats import percentile
from sim.processes import EndpointProcess, ManagedProcess, RosCore, wait_for
from sim.study.design.scene import load_scene, scene_robot
from sim.study.run.protocol import (
    POSE_TOPICS,
    POSE_TYPE,
    PROTOCOL,
    TrialStatus,
    input_delay_from_seq,
    status_to_json,
)
from sim.wire.rosmsgs import JOINT_STATE, deserialize, encode_joint_state, encode_message, to_seconds

HEADSET_RATES_HZ = (72, 90)
PUBLISH_HZ = 100.0
PASSES = ("rendered", "submitted")  # the frame's work with its rendering waited for, and without
SETTLE_S = 3.0  # after entering the session, before the frames counted (shaders compiled, meshes uploaded)
MODES = ("off", "on")  # the tracked body's poses
SLICES = 2  # of each mode, alternating
# the page's status: in a trial (test 1, the approach running), so that the page sends the tracked body
TRIAL = TrialStatus(participant=0, index=1, total=1, phase="moving", condition="vr", test=1, path="straight")
PRESSES = 20  # of the trigger, after the last pass
HOLD_MS = 150  # a person's press of the trigger, and release
DELIVERY_TARGET_S = 0.3  # a press from the page to ROS, its 95th percentile, on a quiet machine
PRESS_WAIT_S = 30.0  # for the page to show a trial, and for its press to arrive: beyond, the bench fails


class PosesReceived:
    """The tracked body's poses that reach ROS, counted as this process's subscriber receives them."""

    def __init__(self) -> None:
        self.count = 0
        self.lock = threading.Lock()

    def add(self, _payload: bytes) -> None:
        with self.lock:
            self.count += 1

    def __call__(self) -> int:
        with self.lock:
            return self.count


def publish_joint_states(port: int, stop: threading.Event, received: PosesReceived) -> None:
    """The Panda's joints on slow sines around its home, at PUBLISH_HZ, until `stop` (at most 10 minutes); the trial's
    status, latched; and `received` counts the poses the page sends."""
    robot = scene_robot(load_scene())
    home = np.asarray(robot.home, dtype=float)
    client = TcpClient("127.0.0.1", port)
    client.register_publisher(robot.joint_states_topic, JOINT_STATE)
    client.register_publisher(PROTOCOL.status[0], PROTOCOL.status[1], latch=True)
    for topic in POSE_TOPICS.values():
        client.subscribe(topic, POSE_TYPE, received.add)
    client.connect()
    client.publish(PROTOCOL.status[0], encode_message(PROTOCOL.status[1], data=status_to_json(TRIAL)))
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


def take(browser: Any, poses_on: bool) -> dict[str, Any]:
    """The page's frames since the last take, and its figures now; then its poses off or on from the next frame."""
    return browser.execute_script(
        "const s = window.vrPage.state(); const t = window.vrFrameTime;"
        "const r = window.vrPage.page.view.renderer; const layer = r.xr.getSession()?.renderState.baseLayer;"
        f"return {{...t.take({str(poses_on).lower()}), jointStates: s.jointStates, inTrial: s.inTrial,"
        " triangles: r.info.render.triangles,"
        " framebuffer: layer ? [layer.framebufferWidth, layer.framebufferHeight] : null, error: s.error};"
    )


def measure(
    browser: Any, url: str, wait_for_rendering: bool, seconds: float, received: PosesReceived
) -> dict[str, dict[str, Any]]:
    """Load the page at `url`, enter the session, and read its figures (after SETTLE_S) by mode of the poses: MODES
    alternating in SLICES slices of each, `seconds` of each mode in all."""
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
    # the rest at the session's start (the participant holding still for the jitter) is over before anything counts
    wait_for(lambda: browser.execute_script("return window.vrPage.state().rest.done;"), 120, "the rest")
    time.sleep(SETTLE_S)
    figures: dict[str, dict[str, Any]] = {
        mode: {
            "work": [],
            "intervals": [],
            "poses": [],
            "pose_work": [],
            "slices": [],
            "joint_states": 0,
            "received": 0,
        }
        for mode in MODES
    }
    latest = take(browser, MODES[0] == "on")  # the settling frames are not counted
    for _ in range(SLICES):
        for k, mode in enumerate(MODES):
            received_before = received()
            time.sleep(seconds / SLICES)
            following = MODES[(k + 1) % len(MODES)]
            frames = take(browser, following == "on")
            if any(on != (mode == "on") for on in frames["posesOn"]):
                raise RuntimeError(f"a frame of the slice with poses {mode} had them the other way")
            kept = figures[mode]
            kept["work"] += frames["work"]
            kept["intervals"] += frames["intervals"]
            kept["poses"] += frames["poses"]
            kept["pose_work"] += frames["poseWork"]
            kept["slices"].append(statistics.median(frames["work"]) if frames["work"] else math.nan)
            kept["joint_states"] += frames["jointStates"] - latest["jointStates"]
            kept["received"] += received() - received_before
            latest = frames
    for kept in figures.values():
        kept.update({key: latest[key] for key in ("triangles", "framebuffer", "error", "inTrial")})
        kept["joint_states_per_s"] = kept["joint_states"] / seconds
        kept["received_per_s"] = kept["received"] / seconds
    return figures


class StopsReceived:
    """The stops that reach this process through the endpoint, each with its arrival on the machine's clock."""

    def __init__(self) -> None:
        self.arrived: queue.Queue[tuple[float, bytes]] = queue.Queue()

    def add(self, payload: bytes) -> None:
        self.arrived.put((time.time(), payload))


def press_latencies(browser: Any, port: int, presses: int) -> list[dict[str, float]]:
    """Press the trigger `presses` times, each in a trial of its own (see Presses above); each press's input delay,
    delivery and the page's clock round trip then (s)."""
    stops = StopsReceived()
    status_topic, status_type = PROTOCOL.status
    stop_topic, stop_type = PROTOCOL.inputs["stop"]
    client = TcpClient("127.0.0.1", port)
    client.register_publisher(status_topic, status_type, latch=True)
    client.subscribe(stop_topic, stop_type, stops.add)
    client.connect()
    controller = "window.emulatedHeadset.controllers.right"
    measured = []
    try:
        for k in range(presses):
            index = TRIAL.index + 1 + k
            trial = TrialStatus(
                participant=0,
                index=index,
                total=TRIAL.index + presses,
                phase="moving",
                condition="vr",
                test=2,
                path="straight",
                motion_start=time.time(),
            )
            client.publish(status_topic, encode_message(status_type, data=status_to_json(trial)))
            shows_trial = f"const s = window.vrPage.state(); return s.index === {index} && s.phase === 'moving';"
            wait_for(partial(browser.execute_script, shows_trial), PRESS_WAIT_S, f"the page to show trial {index}")
            browser.execute_async_script(
                f"const done = arguments[arguments.length - 1]; {controller}.updateButtonValue('trigger', 1);"
                f"setTimeout(() => {{ {controller}.updateButtonValue('trigger', 0); done(); }}, {HOLD_MS});"
            )
            try:
                arrival, payload = stops.arrived.get(timeout=PRESS_WAIT_S)
            except queue.Empty:
                raise RuntimeError(f"the page's press in trial {index} did not arrive in {PRESS_WAIT_S:g} s") from None
            header: Any = deserialize(payload, stop_type)
            stamp = to_seconds(header.stamp)
            if stamp == 0:
                raise RuntimeError(f"the page's press in trial {index} came unstamped: its clock offset is not known")
            round_trip_ms = browser.execute_script("return window.vrPage.page.topics.connection.clock.best()[0];")
            measured.append(
                {
                    "input_delay": input_delay_from_seq(header.seq),
                    "delivery": arrival - stamp,
                    "round_trip": round_trip_ms / 1000,
                }
            )
    finally:
        client.close()
    return measured


def press_report(presses: list[dict[str, float]]) -> list[str]:
    """The presses' latency: the distribution of each part (ms), and the delivery beside its target."""

    def spread(values: list[float]) -> str:
        return f"{statistics.median(values):.1f} / {percentile(values, 95):.1f} / {max(values):.1f}"

    delays = [p["input_delay"] for p in presses if math.isfinite(p["input_delay"])]
    delivery = [1000 * p["delivery"] for p in presses]
    round_trips = [1000 * p["round_trip"] for p in presses]
    p95 = percentile(delivery, 95)
    verdict = "met" if p95 < 1000 * DELIVERY_TARGET_S else "MISSED"
    return [
        f"Presses of the trigger: {len(presses)}, each in a trial of its own, the page's stop to ROS (ms):",
        "",
        "| presses | input delay median / p95 / max | delivery median / p95 / max | clock round trip median / max |",
        "|---|---|---|---|",
        f"| {len(presses)} | {spread([1000 * d for d in delays]) if delays else 'not measured'} | {spread(delivery)} "
        f"| {statistics.median(round_trips):.1f} / {max(round_trips):.1f} |",
        "",
        f"delivery p95 {p95:.1f} ms (target on a quiet machine < {1000 * DELIVERY_TARGET_S:.0f} ms: {verdict}); a "
        "stamp's error is at most half the round trip",
    ]


def summary(work: list[float]) -> tuple[float, float]:
    """The median and the 95th percentile of frames' work (ms)."""
    return (statistics.median(work), percentile(work, 95)) if work else (math.nan, math.nan)


def report(name: str, mode: str, figures: dict[str, Any]) -> str:
    work, intervals, poses = figures["work"], figures["intervals"], figures["poses"]
    median, p95 = summary(work)
    within = {hz: sum(1 for w in work if w <= 1000.0 / hz) / len(work) if work else math.nan for hz in HEADSET_RATES_HZ}
    slices = " / ".join(f"{value:.2f}" for value in figures["slices"])
    return (
        f"| {name} | {mode} | {len(work)} | {median:.2f} | {slices} | {p95:.2f} | {max(work, default=math.nan):.2f} | "
        f"{1000.0 / median:.0f} | {100 * within[72]:.0f} % | {100 * within[90]:.0f} % | "
        f"{statistics.median(intervals) if intervals else math.nan:.2f} | {figures['joint_states_per_s']:.0f} | "
        f"{sum(poses) / len(poses) if poses else math.nan:.2f} | {figures['received_per_s']:.0f} |"
    )


def difference(name: str, figures: dict[str, dict[str, Any]]) -> str:
    """What the poses cost a frame: on minus off, beside the spread of one mode's slices (the measure's noise)."""
    (off_median, off_p95), (on_median, on_p95) = (summary(figures[mode]["work"]) for mode in MODES)
    spread = max(max(figures[mode]["slices"]) - min(figures[mode]["slices"]) for mode in MODES)
    own = figures["on"]["pose_work"]
    return (
        f"pass {name}: poses on minus off: median {on_median - off_median:+.2f} ms, p95 {on_p95 - off_p95:+.2f} ms; "
        f"the slices of one mode differ in their medians by up to {spread:.2f} ms; the poses' own part of a frame: "
        f"mean {statistics.fmean(own) if own else math.nan:.3f} ms, largest {max(own, default=math.nan):.2f} ms"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--seconds", type=float, default=20.0, help="frames counted per pass and mode of the poses (default 20 s)"
    )
    parser.add_argument("--size", default="800,600", help="the browser window (default 800,600)")
    parser.add_argument("--only", choices=PASSES, help="one pass only (default both)")
    parser.add_argument(
        "--presses", type=int, default=PRESSES, help=f"trigger presses after the last pass (default {PRESSES})"
    )
    args = parser.parse_args()
    if not 1 <= args.seconds <= 300:
        parser.error("--seconds must be between 1 and 300")
    if not 0 <= args.presses <= 1000:
        parser.error("--presses must be between 0 and 1000")

    tmp = Path(tempfile.mkdtemp(prefix="vr-frame-bench-"))
    core = RosCore()
    processes: list[ManagedProcess] = []
    stop = threading.Event()
    results: dict[str, dict[str, dict[str, Any]]] = {}
    presses: list[dict[str, float]] = []
    received = PosesReceived()
    try:
        secrets = launch_secrets()  # the launch's proxy secret, for the endpoint and the page's server
        endpoint = EndpointProcess({**core.env, **secrets}, tmp, extra=["--websocket-port", "0"])
        processes.append(endpoint)
        assert endpoint.websocket_port is not None  # asked for with --websocket-port
        vr, url = start_vr_page(endpoint.websocket_port, tmp, frame_time=True, env=secrets)
        processes.append(vr)
        publisher = threading.Thread(target=publish_joint_states, args=(endpoint.port, stop, received), daemon=True)
        publisher.start()
        passes = (args.only,) if args.only else PASSES
        for name in passes:
            wait_for_rendering = name == "rendered"
            with chromium(tmp / f"chromium-{name}", accept_insecure_certs=True, size=args.size) as browser:
                print(f"vr_frame_bench: pass {name} ({args.seconds:g} s a mode) ...", file=sys.stderr, flush=True)
                results[name] = measure(browser, url, wait_for_rendering, args.seconds, received)
                if name == passes[-1] and args.presses:
                    print(f"vr_frame_bench: {args.presses} presses ...", file=sys.stderr, flush=True)
                    presses = press_latencies(browser, endpoint.port, args.presses)
    finally:
        stop.set()
        for process in reversed(processes):
            process.stop()
        core.stop()
        shutil.rmtree(tmp, ignore_errors=True)  # the browsers' profiles, the certificate, the logs

    first = next(iter(results.values()))["on"]
    width, height = first["framebuffer"] or (0, 0)
    print(
        f"VR page frame time: the Panda with its meshes ({first['triangles']} triangles a frame, both eyes), "
        f"the emulated Quest 3's framebuffer {width}x{height}, WebGL in software (SwiftShader), "
        f"headless Chromium, window {args.size}; joint states published at {PUBLISH_HZ:.0f} Hz; in a trial "
        f"(the page in one: {first['inTrial']}), the tracked body's poses off and on in {SLICES} alternating slices "
        f"of {args.seconds / SLICES:g} s each"
    )
    print()
    print(
        "| pass | poses | frames | work median (ms) | median by slice | p95 | max | rate the work allows (Hz) "
        "| frames within 72 Hz (13.9 ms) | within 90 Hz (11.1 ms) | frame interval median (ms) "
        "| joint states received /s | poses sent /frame | poses reaching ROS /s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, figures in results.items():
        for mode in MODES:
            print(report(name, mode, figures[mode]))
    print()
    for name, figures in results.items():
        print(difference(name, figures))
    for name, figures in results.items():
        if figures["on"]["error"]:
            print(f"the page reported, in pass {name}: {figures['on']['error']}")
    if presses:
        print()
        print("\n".join(press_report(presses)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
