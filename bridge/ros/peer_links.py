"""The ROS links of bridged topics that never come up, while the endpoint runs (pure; bridge.ros.peers gathers the
facts, bridge.server's housekeeping acts on them).

In ROS 1 a subscriber connects to its publisher's advertised address. So when a client publishes a topic through the
endpoint, each ROS subscriber the master lists must connect to the endpoint; when a client subscribes, the endpoint
must connect to each ROS publisher. A link the master lists that stays down for PEER_GRACE_S is a problem: the
peer cannot reach the endpoint's advertised address, or the endpoint cannot reach the peer's (refused, timing out,
a name that does not resolve). Each problem is told once to each client that bridges the topic in that direction,
as an __error naming the topic, the peer and its address, and the fix (ROS_IP / ROS_HOSTNAME); /diagnostics shows it
while it lasts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Collection, Hashable, Iterable, Mapping, TypeVar

from bridge.diagnostics import WARN, Status

__all__ = [
    "ANSWERS",
    "PEER_CHECK_S",
    "PEER_CHECK_SHARE",
    "PEER_GRACE_S",
    "PeerLink",
    "PeerProblem",
    "PeerWatch",
    "problem_line",
    "problem_statuses",
]

Client = TypeVar("Client", bound=Hashable)  # whatever stands for a client (the endpoint's sessions)

PEER_CHECK_S = 2.0  # how often the master is asked which links should exist (one getSystemState)
# ...and at most this share of the time: getSystemState's answer grows with the whole graph (80 ms for 1,000
# topics on a loaded machine), so a check waits for at least 1/share of the time the last one took
PEER_CHECK_SHARE = 0.05
ANSWERS = "answers"  # what a peer's address gives from here when connecting to it works
PEER_GRACE_S = 5.0  # how long a listed link may stay down before it is a problem (rospy connects in milliseconds)


@dataclass(frozen=True)
class PeerLink:
    """One TCPROS link the master's registrations call for: `outgoing` when the endpoint publishes `topic` and `peer`
    (a node name) subscribes, so the peer connects to the endpoint; else the endpoint connects to the peer."""

    topic: str
    peer: str
    outgoing: bool


@dataclass(frozen=True)
class PeerProblem:
    link: PeerLink
    down_s: float  # how long the link had been down when found
    peer_uri: str  # the peer's XML-RPC URI as the master has it ("" when it would not say)
    reach: str  # what connecting to the peer's address from here gave: ANSWERS, "connection ... refused", ...; ""
    # when it was not tried
    advertised: str  # the endpoint's own URI, as every peer is told


def problem_line(problem: PeerProblem) -> str:
    """The problem in one line: the topic, the peer and its address, what fails, and the fix."""
    link = problem.link
    where = problem.peer_uri or "an address the master would not give"
    if link.outgoing:
        # its own address refusing us too may mean the node is gone and the master still lists it
        gone = (
            f" (its address gives '{problem.reach}' from here: if the node is gone, `rosnode cleanup` takes it off "
            "the master)"
            if problem.reach and problem.reach != ANSWERS
            else ""
        )
        return (
            f"{link.topic}: the ROS node {link.peer} ({where}) subscribes to it, yet has not connected to this "
            f"endpoint in {problem.down_s:.0f} s, so it receives nothing: that machine cannot reach this node at "
            f"{problem.advertised}. On the endpoint's machine set ROS_IP to its address on that machine's network, "
            "or ROS_HOSTNAME to a name that machine resolves to it, and restart the endpoint" + gone
        )
    if problem.reach == ANSWERS:
        reach = " (its address answers from here, yet no topic connection came up)"
    else:
        reach = f" ({problem.reach})" if problem.reach else ""
    return (
        f"{link.topic}: the endpoint cannot connect to its ROS publisher {link.peer} at {where}{reach} for "
        f"{problem.down_s:.0f} s, so nothing from that node arrives. On that node's machine set ROS_IP to its "
        "address on this machine's network, or ROS_HOSTNAME to a name this machine resolves to it, and restart the "
        "node; if the node is gone, `rosnode cleanup` takes it off the master"
    )


def problem_statuses(node: str, problems: Iterable[PeerProblem]) -> list[Status]:
    """One WARN status per problem, for /diagnostics."""
    statuses = []
    for problem in problems:
        link = problem.link
        statuses.append(
            Status(
                WARN,
                f"{node}: topic {link.topic}: link {'to' if link.outgoing else 'from'} {link.peer}",
                problem_line(problem),
                node,
                (
                    ("topic", link.topic),
                    ("peer node", link.peer),
                    ("peer address", problem.peer_uri or "-"),
                    ("direction", "endpoint publishes, peer subscribes" if link.outgoing else "peer publishes"),
                    ("from here", problem.reach or "-"),
                    ("this node's address", problem.advertised),
                ),
            )
        )
    return statuses


class PeerWatch:
    """Which listed links are down, since when; which are problems; which client was told which. Not thread-safe:
    one thread (housekeeping) drives it."""

    def __init__(self, grace_s: float = PEER_GRACE_S) -> None:
        self._grace_s = grace_s
        self._down_since: dict[PeerLink, float] = {}
        self._problems: dict[PeerLink, PeerProblem] = {}
        self._told: set[tuple[Hashable, PeerLink]] = set()

    @property
    def problems(self) -> list[PeerProblem]:
        return [self._problems[link] for link in sorted(self._problems, key=_order)]

    def observe(
        self, now: float, listed: Collection[PeerLink], up: Collection[PeerLink]
    ) -> list[tuple[PeerLink, float]]:
        """Note the links the master lists and those up at monotonic time `now`. Links no longer down are forgotten
        (a problem that ends is no problem any more). Returns the links down for the grace period that are not yet
        problems, with how long they have been down: the caller looks their peer up and calls `found`."""
        down = set(listed) - set(up)
        self._down_since = {link: self._down_since.get(link, now) for link in down}
        self._problems = {link: problem for link, problem in self._problems.items() if link in down}
        self._told = {(client, link) for client, link in self._told if link in down}
        due = [
            (link, now - since)
            for link, since in self._down_since.items()
            if link not in self._problems and now - since >= self._grace_s
        ]
        return sorted(due, key=lambda entry: _order(entry[0]))

    def found(self, problem: PeerProblem) -> None:
        """A due link, described (its peer looked up): a problem until the link is up or no longer listed."""
        if problem.link in self._down_since:
            self._problems[problem.link] = problem

    def to_tell(
        self, publishing: Mapping[str, Collection[Client]], subscribing: Mapping[str, Collection[Client]]
    ) -> list[tuple[Client, str]]:
        """(client, line) for each problem a client bridging its topic in its direction has not been told yet
        (`publishing`: topic -> clients that publish it, `subscribing`: topic -> those subscribed); each is then
        counted as told. A client that stops bridging the topic is forgotten for it."""

        def bridging(link: PeerLink) -> Collection[Client]:
            return (publishing if link.outgoing else subscribing).get(link.topic, ())

        self._told = {(client, link) for client, link in self._told if client in bridging(link)}
        lines: list[tuple[Client, str]] = []
        for problem in self.problems:
            link = problem.link
            for client in bridging(link):
                if (client, link) not in self._told:
                    self._told.add((client, link))
                    lines.append((client, problem_line(problem)))
        return lines


def _order(link: PeerLink) -> tuple[str, bool, str]:
    return (link.topic, link.outgoing, link.peer)
