"""The links of bridged topics to their ROS peers that never come up (bridge.ros.peer_links, pure)."""

from __future__ import annotations

from bridge.diagnostics import WARN
from bridge.ros.peer_links import ANSWERS, PeerLink, PeerProblem, PeerWatch, problem_line, problem_statuses

ME = "http://endpoint-pc:40001/"
TO_LISTENER = PeerLink("/cmd", "/listener", outgoing=True)  # the endpoint publishes /cmd, /listener subscribes
FROM_TALKER = PeerLink("/state", "/talker", outgoing=False)  # /talker publishes /state, the endpoint subscribes


def problem(link: PeerLink, reach: str = "connection to 127.0.1.1:41234 refused") -> PeerProblem:
    uri = "http://ros-pc:41234/" if link.peer == "/talker" else "http://198.18.71.1:39999/"
    return PeerProblem(link, 6.0, uri, reach, ME)


def found_after_grace(watch: PeerWatch, *links: PeerLink) -> None:
    listed = set(links)
    assert watch.observe(0.0, listed, set()) == []
    due = watch.observe(5.0, listed, set())
    assert [link for link, _ in due] == sorted(links, key=lambda link: (link.topic, link.outgoing, link.peer))
    assert all(down_s == 5.0 for _, down_s in due)
    for link, _ in due:
        watch.found(problem(link))


def test_a_link_up_or_down_less_than_the_grace_period_is_no_problem() -> None:
    watch = PeerWatch(grace_s=5.0)
    assert watch.observe(0.0, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER}) == []
    assert watch.observe(4.9, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER}) == []
    # up at last: its clock starts again if it goes down
    assert watch.observe(5.0, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER, FROM_TALKER}) == []
    assert watch.observe(9.0, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER}) == []
    assert watch.observe(13.0, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER}) == []
    assert watch.observe(14.0, {TO_LISTENER, FROM_TALKER}, {TO_LISTENER}) == [(FROM_TALKER, 5.0)]
    # a link up that the master does not list (the peer just unregistered) is no problem either
    assert watch.problems == []


def test_a_link_down_for_the_grace_period_is_due_once_and_a_problem_once_found() -> None:
    watch = PeerWatch(grace_s=5.0)
    found_after_grace(watch, TO_LISTENER, FROM_TALKER)
    assert watch.observe(7.0, {TO_LISTENER, FROM_TALKER}, set()) == []  # not due again
    assert [p.link for p in watch.problems] == [TO_LISTENER, FROM_TALKER]


def test_a_due_link_that_came_up_while_being_described_is_no_problem() -> None:
    watch = PeerWatch(grace_s=5.0)
    watch.observe(0.0, {FROM_TALKER}, set())
    assert watch.observe(5.0, {FROM_TALKER}, set()) == [(FROM_TALKER, 5.0)]
    watch.observe(6.0, {FROM_TALKER}, {FROM_TALKER})
    watch.found(problem(FROM_TALKER))
    assert watch.problems == []


def test_a_problem_ends_when_its_link_comes_up_or_its_peer_leaves_the_master() -> None:
    watch = PeerWatch(grace_s=5.0)
    found_after_grace(watch, TO_LISTENER, FROM_TALKER)
    watch.observe(8.0, {TO_LISTENER, FROM_TALKER}, {FROM_TALKER})
    assert [p.link for p in watch.problems] == [TO_LISTENER]
    watch.observe(9.0, set(), set())
    assert watch.problems == []


def test_each_client_bridging_the_topic_that_way_is_told_once() -> None:
    watch = PeerWatch(grace_s=5.0)
    found_after_grace(watch, TO_LISTENER, FROM_TALKER)
    publishing = {"/cmd": ["unity", "tablet"]}
    subscribing = {"/state": ["unity"], "/cmd": ["viewer"]}  # viewer subscribes to /cmd: its publisher is the endpoint
    told = watch.to_tell(publishing, subscribing)
    assert [client for client, _ in told] == ["unity", "tablet", "unity"]
    assert told[0][1] == problem_line(watch.problems[0]) and told[2][1] == problem_line(watch.problems[1])
    watch.observe(7.0, {TO_LISTENER, FROM_TALKER}, set())
    assert watch.to_tell(publishing, subscribing) == []
    # a client that comes later is told; one that stopped bridging the topic and comes back is told again
    assert watch.to_tell({"/cmd": ["unity", "tablet", "late"]}, {}) == [("late", told[0][1])]
    assert watch.to_tell({"/cmd": ["unity", "tablet", "late"]}, {"/state": ["unity"]}) == [("unity", told[2][1])]


def test_a_problem_that_ends_and_comes_back_is_told_again() -> None:
    watch = PeerWatch(grace_s=5.0)
    found_after_grace(watch, FROM_TALKER)
    assert len(watch.to_tell({}, {"/state": ["unity"]})) == 1
    watch.observe(6.0, {FROM_TALKER}, {FROM_TALKER})
    watch.observe(7.0, {FROM_TALKER}, set())
    assert watch.observe(12.0, {FROM_TALKER}, set()) == [(FROM_TALKER, 5.0)]
    watch.found(problem(FROM_TALKER))
    assert len(watch.to_tell({}, {"/state": ["unity"]})) == 1


def test_a_peer_that_cannot_reach_the_endpoint_is_named_with_the_endpoints_fix() -> None:
    line = problem_line(problem(TO_LISTENER, reach=ANSWERS))
    assert line.startswith("/cmd: the ROS node /listener (http://198.18.71.1:39999/) subscribes to it, yet has not")
    assert f"that machine cannot reach this node at {ME}" in line
    assert "On the endpoint's machine set ROS_IP to its address on that machine's network, or ROS_HOSTNAME" in line
    assert "rosnode cleanup" not in line  # it answers from here: it is there


def test_a_subscriber_whose_own_address_refuses_us_may_be_gone() -> None:
    line = problem_line(problem(TO_LISTENER, reach="connection to 198.18.71.1:39999 refused"))
    assert "(its address gives 'connection to 198.18.71.1:39999 refused' from here: if the node is gone" in line


def test_a_publisher_the_endpoint_cannot_reach_is_named_with_what_connecting_gave_and_its_fix() -> None:
    line = problem_line(problem(FROM_TALKER))
    assert line.startswith(
        "/state: the endpoint cannot connect to its ROS publisher /talker at http://ros-pc:41234/ "
        "(connection to 127.0.1.1:41234 refused) for 6 s"
    )
    assert "On that node's machine set ROS_IP to its address on this machine's network, or ROS_HOSTNAME" in line
    answers = problem_line(problem(FROM_TALKER, reach=ANSWERS))
    assert "(its address answers from here, yet no topic connection came up)" in answers
    unknown = problem_line(PeerProblem(FROM_TALKER, 6.0, "", "", ME))
    assert "/talker at an address the master would not give for 6 s" in unknown


def test_diagnostics_show_each_problem_as_a_warning() -> None:
    statuses = problem_statuses("/ros_tcp_endpoint", [problem(TO_LISTENER), problem(FROM_TALKER)])
    assert [s.name for s in statuses] == [
        "/ros_tcp_endpoint: topic /cmd: link to /listener",
        "/ros_tcp_endpoint: topic /state: link from /talker",
    ]
    assert all(s.level == WARN for s in statuses)
    values = dict(statuses[1].values)
    assert values["peer node"] == "/talker" and values["peer address"] == "http://ros-pc:41234/"
    assert statuses[1].message == problem_line(problem(FROM_TALKER))
