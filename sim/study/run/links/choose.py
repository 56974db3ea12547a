"""Each condition's robot link, from the runner's options: the stream (one, shared by every condition without a
trajectory controller) or a trajectory controller per spec."""

from __future__ import annotations

import threading
from collections.abc import Iterable, Mapping
from typing import Any

from sim.control.stepper import Pacing
from sim.robots import RobotSpec
from sim.study.run.links.base import RobotLink
from sim.study.run.links.specs import TrajectoryLinkSpec
from sim.study.run.links.stream import StreamLink
from sim.study.run.links.trajectory import TrajectoryLink

__all__ = ["unique", "make_links"]


def unique(links: Iterable[RobotLink]) -> list[RobotLink]:
    """Each link once (conditions may share one), in the order first met."""
    seen: dict[int, RobotLink] = {}
    for link in links:
        seen.setdefault(id(link), link)
    return list(seen.values())


def make_links(
    robot: RobotSpec,
    conditions: Iterable[str],
    pacing: Pacing,
    stop: threading.Event,
    trajectory_links: Mapping[str, TrajectoryLinkSpec],
    watched: tuple[str, Any],
) -> dict[str, RobotLink]:
    """Each condition's link: the stream (one, shared) unless a trajectory controller is named for it. The stream's
    partner must also take the `watched` (topic, publisher): the runner's status, which the endpoint relays to a VR
    scene, so it waits for that link too."""
    links: dict[str, RobotLink] = {}
    stream: StreamLink | None = None
    controllers: dict[TrajectoryLinkSpec, TrajectoryLink] = {}
    for condition in conditions:
        spec = trajectory_links.get(condition)
        if spec is None:
            if stream is None:
                stream = StreamLink(robot, pacing, stop, [watched])
            links[condition] = stream
        else:
            if spec not in controllers:
                controllers[spec] = TrajectoryLink(robot, spec, pacing.dt, stop)
            links[condition] = controllers[spec]
    return links
