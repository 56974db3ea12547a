"""Benchmark of the ROS-TCP endpoint (`python -m bridge`) against the plain rospy ceiling, on one machine.

Run: `.venv/bin/python -m bench.endpoint_bench [--quick] [--seconds S] [--only PHASE ...] [--keep-logs]
[--ab REVISION [--their-first]]` from the repository root.

Method. The script starts its own roscore (sim.processes.RosCore, free port, private ROS_HOME/ROS_LOG_DIR) and one
endpoint subprocess, and drives it from this process with `bridge.client.TcpClient`s (the Python twin of Unity's
client). Every ROS-side role is a separate rospy process (bench.endpoint_rosnode), so no two roles share a
GIL. All messages are one serialized 7-joint sensor_msgs/JointState; ping and stream messages carry a sequence
number and a CLOCK_MONOTONIC stamp in their header, so latency is computed from the bytes. The rospy nodes use a
raw (bytes-only) message class, like the endpoint, so the ceiling is rospy's transport, not its serializer.

  1. TCP->ROS: a TcpClient writes JointState frames as fast as it can (bounded by count and time) to the
     endpoint; a rospy subscriber process counts arrivals; rate = arrivals / (last - first arrival).
     Ceiling: a rospy publisher process flooding the same bytes to the same kind of subscriber process, in both
     publisher modes: synchronous (queue_size=None; usually the faster, and the one judged) and queued (queue_size
     100, what rospy nodes normally use; shown, not judged). Each throughput row names the reference it divides by.
     Every throughput flow (1 and 2) runs in 3 interleaved rounds (1 with --quick): one 5 s window varies by about
     +-12 % between runs on two cores, so each row shows the median round and the range of rounds.
  2. ROS->TCP: the same rospy flood publisher, received by a TcpClient through the endpoint. Same ceilings.
  3. RTT: a rospy relay process republishes /bench/ping bytes unchanged on /bench/pong. A TcpClient pings at
     100 Hz and 1 kHz (fixed schedule, no catch-up bursts) and times the pongs; the ceiling is a rospy process
     pinging the same relay on its own topic pair. The relay's CPU per round trip is the "rospy node" reference
     for the endpoint's CPU per round trip.
  4. Fan-out: 10 TcpClients subscribe to one topic published at 1 kHz for the window; delivered fraction per
     client (distinct sequence numbers received / published) and one-way latency.
  5. Endpoint CPU (utime + stime of all its threads, measuring.procfs) per 10k messages, for runs 1-4.
  6. Hardening: (a) raw sockets announce a 0xFFFFFFF0-byte payload, then a 0xFFFFFFF0-byte destination, while
     another TcpClient receives a 1 kHz stream: endpoint RSS increase (VmRSS sampled every 5 ms) and that client's
     longest inter-arrival gap; (b) a client subscribes to a 1 kHz stream and never reads (tiny SO_RCVBUF) for
     60 s: endpoint RSS growth, and what a well-behaved client on the same topic still receives.
  7. Large messages: a 1280x720 RGB Image (2.7 MB) and a 1 MiB PointCloud2, each way, in interleaved rounds of the
     same run. TCP->ROS is read by a rospy subscriber process; its reference is a rospy sync publisher read by the
     same kind of subscriber (so both rates are bounded by that subscriber's read path). ROS->TCP has a rospy
     publisher of queue_size 10 as the source; its reference is the same source read by a raw TCPROS reader
     (bench.tcpros_reader: its own handshake, recv_into one buffer), not by a rospy subscriber, whose Python
     read path copies each message several times and reads a 2.7 MB image at a third of the rate the source
     delivers or less. Then TCP->ROS loss, a 1 MiB round trip at 30 Hz against rospy alone through the same relay,
     with the endpoint's CPU meanwhile, and its RSS after it all.
  8. The Unity-typical mix: down 4 PoseStamped and 4 JointState topics at 60 Hz and TF at 100 Hz, up a PoseStamped
     and a JointState at 60 Hz, for two windows: what arrived of what was sent, one-way latency each way, and the
     endpoint's CPU meanwhile.
  9. WebSocket clients (--websocket-port): JointState and the 2.7 MB Image both ways through WebSocket clients
     (bridge.client.TcpClient(websocket=True), as a browser or a Unity WebGL build connects) against TCP clients of
     the same endpoint in the same rounds, with the endpoint's CPU per message. The phase has an endpoint of its
     own with the WebSocket port open; every other phase's endpoint serves TCP only (the default). Skipped for a
     revision without the transport.
`--quick` shortens every window (2 s), the RTT sample counts and the soak (10 s) for a short run; `--seconds S`
sets the windows and the soak to S (the smoke test runs a phase with 0.5).
`--ab REVISION` runs REVISION's endpoint (a git worktree of it) beside this tree's, phase by phase alternately on
one roscore, and prints both tables and a comparison with the ratios. `--markdown` also prints README's performance
and WebSocket tables of the figures (the other revision's in the last column).

Percentiles are measuring.stats.percentile (numpy's linear interpolation; until the benches shared it, this bench
took the nearest rank, which differs from it by at most one sample's spacing).

The modules, one concern each: settings (the run's knobs), records (a row, a client's arrivals, a flow), harness
(the endpoint under test, its client and node processes), flows (one throughput flow each way and its references),
throughput, large, latency (round trips, fan-out), mix (the Unity-typical mix), hardening (the 4 GiB prefix, the
never-reading client), websocket, tables (the table and the A/B comparison), markdown (README's tables of the
figures, `--markdown`), driver (the phases for one or two endpoints on one roscore, the A/B worktree) and __main__
(the command line).

Everything is loopback; every loop is bounded in count and time; every process is stopped by PID.
"""
