"""What the tests and the benchmarks measure the endpoint with, and how: one package both import (never installed
for users: setup.py and the catkin packages leave it out).

- stats: the one percentile (numpy's default, linear interpolation between the closest ranks);
- procfs: a process's figures from /proc (CPU seconds, RSS, threads, descriptors) and the sockets listening on a port;
- link: a slow network link emulated in user space (rate, delay, a small queue);
- frames: the endpoint's frames as a raw client reads them;
- abuse: abusive clients (connections reset mid-way, mutated streams of valid frames);
- endpoint: when a started endpoint has settled (the baseline of its figures);
- browser: a headless Chromium and the VR page's server with its emulated headset (the page's frame time).

It imports the standard library, `bridge` (frames, the protocol), sim.processes (and selenium, in the browser's
start) and nothing of tests/ or bench/; it runs on Python 3.8 like the endpoint. Every error raised on purpose is a
MeasuringError.
"""
