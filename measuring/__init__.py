"""What the tests and the benchmarks measure the endpoint with, and how: one package both import (never installed
for users: setup.py and the catkin packages leave it out).

- stats: the one percentile (numpy's default, linear interpolation between the closest ranks);
- procfs: a process's figures from /proc (CPU seconds, RSS, threads, descriptors) and the sockets listening on a port;
- link: a slow network link emulated in user space (rate, delay, a small queue);
- frames: the endpoint's frames as a raw client reads them;
- abuse: abusive clients (connections reset mid-way, mutated streams of valid frames).

It imports the standard library, `bridge` (frames, the protocol) and nothing of tests/ or bench/, and runs on
Python 3.8 like the endpoint. Every error raised on purpose is a MeasuringError.
"""
