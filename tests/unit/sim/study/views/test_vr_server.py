"""What the VR page's server (sim.study.views.vr.server) sends a browser, on loopback over plain HTTP: the page and
every module it imports, followed from index.html as a browser does. Without --emulate-headset and --frame-time, a
participant's page holds neither the tests' probe nor the frame-time instrument, and cannot fetch them. The page
is opened by its address with the launch's key, and every module by the cookie that keeps it, as a browser does."""

from __future__ import annotations

import asyncio
import http.client
import re

from sim.study.views.vr.access import Access
from sim.study.views.vr.server import PageServer
from sim.study.views.vr.site import (
    BUTTON_PAGE_FILES,
    EMULATION_FILES,
    FRAME_TIME_FILES,
    GAMEPAD_EMULATION_FILES,
    PAGE_FILES,
    Site,
    make_button_site,
)

# What only the probe and the instrument say: their globals, the pixel read back, the bench's old URL switch
INSTRUMENT_WORDS = (
    "vrPage",
    "vrFrameTime",
    "readPixels",
    "frametime",
    "emulatedHeadset",
    "buttonPage",
    "emulatedGamepad",
    "defineProperty",
)
_SCRIPT = re.compile(r'<script type="module" src="/app/([^"]+)"')
_IMPORT = re.compile(r"""(?:\bfrom|\bimport)\s*\(?\s*'\./([^']+)'""")


def served(
    site: Site, instruments: tuple[str, ...] = EMULATION_FILES + FRAME_TIME_FILES
) -> tuple[dict[str, str], dict[str, int]]:
    """The page and the modules a browser loads from it ({name: text}, "/" for the page), and the status of a GET of
    each of `instruments`' modules."""

    async def main() -> tuple[dict[str, str], dict[str, int]]:
        access = Access("the-key", frozenset(), "http")
        server = PageServer(site, ("127.0.0.1", 9), "127.0.0.1", 0, None, access, log=lambda _: None)
        port = await server.start()
        loop = asyncio.get_running_loop()
        cookie = {}

        def get(path: str) -> tuple[int, str]:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
            try:
                connection.request("GET", path, headers=cookie)
                response = connection.getresponse()
                if response.getheader("Set-Cookie"):
                    cookie["Cookie"] = response.getheader("Set-Cookie").split(";", 1)[0]
                return response.status, response.read().decode()
            finally:
                connection.close()

        try:
            assert (await loop.run_in_executor(None, get, "/"))[0] == 403  # not without the key
            status, page = await loop.run_in_executor(None, get, "/?key=the-key")
            assert status == 200 and cookie == {"Cookie": f"sim_study_key_{port}=the-key"}
            loaded = {"/": page}
            waiting = _SCRIPT.findall(page)
            while waiting:
                name = waiting.pop()
                if name in loaded:
                    continue
                status, text = await loop.run_in_executor(None, get, f"/app/{name}")
                assert status == 200, name
                loaded[name] = text
                waiting += _IMPORT.findall(text)
            statuses = {}
            for name in instruments:
                statuses[name] = (await loop.run_in_executor(None, get, f"/app/{name}"))[0]
            return loaded, statuses
        finally:
            stopped = asyncio.Event()
            stopped.set()
            await server.serve_until(stopped)

    return asyncio.run(main())


def site(emulation: bool = False, frame_time: bool = False) -> Site:
    return Site("<robot name='r'/>", (), {}, emulation=emulation, frame_time=frame_time)


def test_a_participants_page_has_no_probe_and_no_frame_time_code() -> None:
    loaded, statuses = served(site())
    # every module of the page is loaded, and nothing else
    assert set(loaded) - {"/"} == {name for name in PAGE_FILES if name.endswith(".js")}
    found = {name: [word for word in INSTRUMENT_WORDS if word in text] for name, text in loaded.items()}
    assert {name: words for name, words in found.items() if words} == {}
    assert statuses == {name: 404 for name in EMULATION_FILES + FRAME_TIME_FILES}


def test_the_emulated_headset_brings_the_probe_and_the_bench_flag_the_frame_time() -> None:
    loaded, statuses = served(site(emulation=True))
    assert "window.vrPage" in loaded["probe.js"] and "emulation.js" in loaded
    assert "frametime.js" not in loaded and statuses["frametime.js"] == 404
    loaded, statuses = served(site(frame_time=True))
    assert "window.vrFrameTime" in loaded["frametime.js"] and "readPixels" in loaded["frametime.js"]
    assert "probe.js" not in loaded and statuses["probe.js"] == 404
    # the emulated headset first: it installs WebXR before the page asks for it
    loaded, _ = served(site(emulation=True, frame_time=True))
    scripts = _SCRIPT.findall(loaded["/"])
    assert scripts == ["emulation.js", "probe.js", "frametime.js", "page.js"]


def test_the_button_page_loads_its_modules_and_only_with_the_emulated_gamepad_the_probe() -> None:
    loaded, statuses = served(make_button_site(), GAMEPAD_EMULATION_FILES + EMULATION_FILES)
    assert set(loaded) - {"/"} == {name for name in BUTTON_PAGE_FILES if name.endswith(".js")}
    found = {name: [word for word in INSTRUMENT_WORDS if word in text] for name, text in loaded.items()}
    assert {name: words for name, words in found.items() if words} == {}
    assert statuses == {name: 404 for name in GAMEPAD_EMULATION_FILES + EMULATION_FILES}
    assert "three" not in loaded["/"] and "Enter VR" not in loaded["/"]
    loaded, _ = served(make_button_site(emulation=True), ())
    # the emulated gamepad first: it replaces navigator.getGamepads before the page reads it
    assert _SCRIPT.findall(loaded["/"]) == ["gamepademulation.js", "buttonprobe.js", "button.js"]
    assert "window.buttonPage" in loaded["buttonprobe.js"]
