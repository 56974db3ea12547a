"""The run's knobs: windows, rounds and sample counts (full, --quick, or --seconds), and the endpoint to run."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

PUBLISH_QUEUE = 100  # queue_size of the client's __publish and of the queued rospy flood publisher
LARGE_ROS_QUEUE = 10  # queue_size of the rospy publisher feeding large messages to the endpoint


@dataclass(frozen=True)
class Settings:
    window_s: float
    throughput_rounds: int  # interleaved rounds of every throughput flow; the median round is judged
    rtt_samples: dict[int, int]  # rate in Hz -> number of pings
    soak_s: float
    quick: bool
    large_rtt_samples: int = 300
    bridge_dir: Path | None = None  # another checkout's `bridge` package, for A/B runs of a change
    endpoint_args: tuple[str, ...] = ()


def settings_for(quick: bool, seconds: float | None, endpoint_args: tuple[str, ...]) -> Settings:
    """The full run, or --quick's; `seconds` (--seconds) then sets every window and the soak, and scales the RTT
    and round-trip sample counts to about one window each."""
    if quick:
        settings = Settings(2.0, 1, {100: 300, 1000: 1000}, 10.0, True, 90, endpoint_args=endpoint_args)
    else:
        settings = Settings(5.0, 3, {100: 2000, 1000: 5000}, 60.0, False, endpoint_args=endpoint_args)
    if seconds is None:
        return settings
    return Settings(
        window_s=seconds,
        throughput_rounds=settings.throughput_rounds,
        rtt_samples={hz: max(10, int(hz * seconds)) for hz in settings.rtt_samples},
        soak_s=seconds,
        quick=settings.quick,
        large_rtt_samples=max(settings.throughput_rounds, int(30 * seconds)),
        endpoint_args=endpoint_args,
    )
