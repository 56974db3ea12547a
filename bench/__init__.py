"""The benchmarks: speed, memory and accuracy figures, printed as tables; each judges against its targets where it
has them. Run each from the repository root as a module, e.g. `python -m bench.endpoint_bench --quick`; the smoke
tests (tests/integration/test_benches.py) run every one for about a second.

What they measure with (percentiles, a process's figures from /proc, the slow link, raw frames, abusive clients) is
the measuring package, shared with the tests. Here: the benchmarks, and what only they use: bench.messages (the
stamped test messages and pacing), bench.endpoint_rosnode (the rospy roles, one process each) and
bench.tcpros_reader (the raw TCPROS reference reader).
"""
