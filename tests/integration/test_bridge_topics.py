"""Topics through a real endpoint on a real roscore: byte-exact both ways, many clients, registrations, removal."""

from __future__ import annotations

import json
import time

import pytest
import rospy  # noqa: F401 - the session's rospy node (ros_node fixture) is what the tests use
from geometry_msgs.msg import Point, Pose, Quaternion
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from tests.integration.bridge_helpers import (
    DiagnosticsInbox,
    Inbox,
    RawConnection,
    RosInbox,
    bridge,  # noqa: F401 - module-scoped endpoint fixture
    serialize,
    service_exists,
    start_endpoint,
    status_values,
    tcp_client,
    unique,
    wait_no_subscribers,
    wait_subscribers,
)
from tests.rosenv import wait_for

pytestmark = pytest.mark.lane("endpoint", on=("noetic",))

JOINTS = [f"joint_{index}" for index in range(1, 8)]


def joint_state(seq: int, step: int) -> JointState:
    return JointState(
        header=Header(seq=seq, stamp=rospy.Time(1700000000 + step, 123456789), frame_id="base_link"),
        name=JOINTS,
        position=[0.1 * index + step for index in range(7)],
        velocity=[-0.01 * index for index in range(7)],
        effort=[1.5 * index for index in range(7)],
    )


def joint_trajectory(seq: int, step: int) -> JointTrajectory:
    return JointTrajectory(
        header=Header(seq=seq, stamp=rospy.Time(42, step), frame_id="world"),
        joint_names=JOINTS,
        points=[
            JointTrajectoryPoint(
                positions=[0.01 * (index + point) for index in range(7)],
                velocities=[0.1] * 7,
                accelerations=[],
                effort=[float(step)] * 7,
                time_from_start=rospy.Duration(point, 500_000_000),
            )
            for point in range(3)
        ],
    )


def clock(seq: int, step: int) -> Clock:
    return Clock(clock=rospy.Time(1000 + step, seq))


def pose(seq: int, step: int) -> Pose:
    return Pose(position=Point(1.0 + step, -2.5, 3.25), orientation=Quaternion(0.0, 0.0, 0.7071068, 0.7071068))


MESSAGES = {
    "sensor_msgs/JointState": (JointState, joint_state),
    "trajectory_msgs/JointTrajectory": (JointTrajectory, joint_trajectory),
    "rosgraph_msgs/Clock": (Clock, clock),
    "geometry_msgs/Pose": (Pose, pose),
}


@pytest.mark.parametrize("message_name", list(MESSAGES))
def test_ros_to_client_is_byte_exact(bridge, ros_node, message_name: str) -> None:
    cls, make = MESSAGES[message_name]
    topic = unique("to_client")
    publisher = ros_node.Publisher(topic, cls, queue_size=10)
    with RawConnection(bridge.port) as client:
        client.subscribe(topic, message_name)
        client.sync()
        wait_subscribers(publisher)
        expected = []
        for step in range(3):
            message = make(1000 + step, step)
            publisher.publish(message)
            expected.append(serialize(message))  # after publish: rospy has stamped header.seq, if any
        for payload in expected:
            frame = client.wait_frame(lambda f: f.destination == topic, f"message on {topic}")
            assert frame.payload == payload
        assert not client.errors()
    publisher.unregister()


@pytest.mark.parametrize("message_name", list(MESSAGES))
def test_client_to_ros_is_byte_exact_and_keeps_header_seq(bridge, ros_node, message_name: str) -> None:
    cls, make = MESSAGES[message_name]
    topic = unique("to_ros")
    inbox = RosInbox(ros_node, topic)
    payloads = [serialize(make(seq, step)) for step, seq in enumerate((7, 4242, 7))]  # seq not monotonic
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, message_name)
        client.sync()
        inbox.wait_connected()
        for payload in payloads:
            client.send_frame(topic, payload)
        assert inbox.wait_count(3) == payloads
        if hasattr(cls(), "header"):
            assert [cls().deserialize(item).header.seq for item in inbox.snapshot()] == [7, 4242, 7]
        client.sync()
        assert not client.errors()
    inbox.close()


def test_relative_topic_names_come_back_as_the_client_spelled_them(bridge, ros_node) -> None:
    topic = unique("relative").lstrip("/")
    publisher = ros_node.Publisher("/" + topic, String, queue_size=10)
    with RawConnection(bridge.port) as client:
        client.subscribe(topic, "std_msgs/String")
        client.sync()
        wait_subscribers(publisher)
        publisher.publish(String("hello"))
        frame = client.wait_frame(lambda f: not f.destination.startswith("__"), "a topic frame")
        assert frame.destination == topic and frame.payload == serialize(String("hello"))


def test_two_clients_get_only_what_they_subscribed_to(bridge, ros_node) -> None:
    topic_a, topic_b = unique("only_a"), unique("only_b")
    publisher_a = ros_node.Publisher(topic_a, String, queue_size=10)
    publisher_b = ros_node.Publisher(topic_b, String, queue_size=10)
    with RawConnection(bridge.port) as client_a, RawConnection(bridge.port) as client_b:
        client_a.subscribe(topic_a, "std_msgs/String")
        client_b.subscribe(topic_b, "std_msgs/String")
        client_a.sync()
        client_b.sync()
        wait_subscribers(publisher_a)
        wait_subscribers(publisher_b)
        for index in range(3):
            publisher_a.publish(String(f"a{index}"))
            publisher_b.publish(String(f"b{index}"))
        for client, topic, letter in ((client_a, topic_a, "a"), (client_b, topic_b, "b")):
            for index in range(3):
                frame = client.wait_frame(lambda f, topic=topic: f.destination == topic, f"message on {topic}")
                assert frame.payload == serialize(String(f"{letter}{index}"))
            client.sync()
        assert {f.destination for f in client_a.received if not f.destination.startswith("__")} == {topic_a}
        assert {f.destination for f in client_b.received if not f.destination.startswith("__")} == {topic_b}


def test_ten_clients_each_get_every_message_on_a_shared_topic_and_only_their_own_topic(bridge, ros_node) -> None:
    shared = unique("shared")
    shared_publisher = ros_node.Publisher(shared, String, queue_size=100)
    own_topics = [unique(f"own{index}") for index in range(10)]
    own_publishers = [ros_node.Publisher(topic, String, queue_size=10) for topic in own_topics]
    clients, shared_inboxes, own_inboxes = [], [], []
    try:
        for own_topic in own_topics:
            client = tcp_client(bridge.port, reconnect=False)
            clients.append(client)
            shared_inbox, own_inbox = Inbox(), Inbox()
            client.subscribe(shared, "std_msgs/String", shared_inbox)
            client.subscribe(own_topic, "std_msgs/String", own_inbox)
            shared_inboxes.append(shared_inbox)
            own_inboxes.append(own_inbox)
        for client in clients:
            client.topic_list()  # round trip: this client's subscriptions are in place
        wait_subscribers(shared_publisher)
        for publisher in own_publishers:
            wait_subscribers(publisher)
        expected = [serialize(String(f"shared {index}")) for index in range(20)]
        for index in range(20):
            shared_publisher.publish(String(f"shared {index}"))
        for index, publisher in enumerate(own_publishers):
            publisher.publish(String(f"own {index}"))
        for index in range(10):
            assert shared_inboxes[index].wait_count(20) == expected
            assert own_inboxes[index].wait_count(1) == [serialize(String(f"own {index}"))]
        for client in clients:
            client.topic_list()  # anything else in flight would have arrived by now
        assert all(len(inbox) == 20 for inbox in shared_inboxes)
        assert all(len(inbox) == 1 for inbox in own_inboxes)
        assert all(client.errors == [] and client.connections == 1 for client in clients)
    finally:
        for client in clients:
            client.close()


def test_registering_the_same_topic_twice_is_harmless(bridge, ros_node) -> None:
    sub_topic, pub_topic = unique("twice_sub"), unique("twice_pub")
    publisher = ros_node.Publisher(sub_topic, String, queue_size=10)
    inbox = RosInbox(ros_node, pub_topic)
    with RawConnection(bridge.port) as client:
        for _ in range(2):
            client.subscribe(sub_topic, "std_msgs/String")
            client.register_publisher(pub_topic, "std_msgs/String")
        client.sync()
        wait_subscribers(publisher)
        inbox.wait_connected()
        for text in ("one", "two", "sentinel"):
            publisher.publish(String(text))
        client.wait_frame(lambda f: f.payload == serialize(String("sentinel")), "the sentinel")
        # A duplicate subscription would deliver each message twice, before the next one.
        assert client.messages(sub_topic) == [serialize(String(text)) for text in ("one", "two", "sentinel")]
        client.send_frame(pub_topic, serialize(String("once")))
        client.send_frame(pub_topic, serialize(String("sentinel")))
        assert inbox.wait_count(2) == [serialize(String("once")), serialize(String("sentinel"))]
        assert client.errors() == []
    inbox.close()


def test_topic_list_reports_topics_and_types(bridge, ros_node) -> None:
    topic = unique("listed")
    publisher = ros_node.Publisher(topic, JointState, queue_size=1)
    with RawConnection(bridge.port) as client:
        topics = wait_for(lambda: (t := client.topic_list()) and topic in t and t, 10, f"{topic} in the topic list")
        assert topics[topic] == "sensor_msgs/JointState"
        assert topics["/rosout"] == "rosgraph_msgs/Log"
    publisher.unregister()


def test_remove_subscriber_stops_delivery_to_that_client_only(bridge, ros_node) -> None:
    topic = unique("remove_sub")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    with RawConnection(bridge.port) as leaving, RawConnection(bridge.port) as staying:
        for client in (leaving, staying):
            client.subscribe(topic, "std_msgs/String")
            client.sync()
        wait_subscribers(publisher)
        publisher.publish(String("before"))
        for client in (leaving, staying):
            client.wait_frame(lambda f: f.destination == topic, "the first message")
        leaving.command("__remove_subscriber", topic=topic)
        leaving.sync()
        publisher.publish(String("after"))
        staying.wait_frame(lambda f: f.payload == serialize(String("after")), "the second message")
        leaving.sync()  # queued after "after" would have been, had it been sent to this client
        assert leaving.messages(topic) == [serialize(String("before"))]
        staying.command("__remove_subscriber", topic=topic)
        wait_no_subscribers(publisher)  # the last client gone: the endpoint leaves the topic
        assert leaving.errors() == [] and staying.errors() == []


def test_remove_publisher(bridge, ros_node) -> None:
    topic = unique("remove_pub")
    inbox = RosInbox(ros_node, topic)
    with RawConnection(bridge.port) as client:
        client.register_publisher(topic, "std_msgs/String")
        client.sync()
        inbox.wait_connected()
        client.send_frame(topic, serialize(String("published")))
        inbox.wait_count(1)
        client.command("__remove_publisher", topic=topic)
        wait_for(lambda: inbox.subscriber.get_num_connections() == 0, 10, "the endpoint to unadvertise")
        client.send_frame(topic, serialize(String("refused")))
        assert topic in client.expect_error("has not registered with __publish")
    assert inbox.snapshot() == [serialize(String("published"))]
    inbox.close()


def test_remove_unity_service_takes_the_service_off_the_graph(bridge, ros_node) -> None:
    service = unique("remove_unity_srv")
    with RawConnection(bridge.port) as client:
        client.offer_service(ros_node, service, "std_srvs/Trigger")
        client.command("__remove_unity_service", topic=service)
        wait_for(lambda: not service_exists(ros_node, service), 10, f"{service} withdrawn")
        client.sync()
        assert client.errors() == []


def test_removing_what_was_never_registered_is_harmless(bridge) -> None:
    with RawConnection(bridge.port) as client:
        for kind in ("subscriber", "publisher", "ros_service", "unity_service"):
            client.command(f"__remove_{kind}", topic=unique("never"))
        client.sync()
        assert client.errors() == []


def test_keepalives_are_ignored(bridge) -> None:
    with RawConnection(bridge.port) as client:
        client.send(b"\0" * 8 * 50)
        client.sync()
        assert client.errors() == []


def test_the_newest_connectors_subscribe_and_ping_are_served(bridge, ros_node) -> None:
    """ROS-TCP-Connector's dev branch: __subscribe may carry queue_size, and __ping is answered with the client's
    own request_time (plus the endpoint's ROS time). A field the endpoint does not know is ignored, with one __warn
    per command and field."""
    topic = unique("newest_connector")
    publisher = ros_node.Publisher(topic, String, queue_size=10)
    request_time = "2026-11-23T04:00:00.1234567Z"  # Unity's DateTime round-trip format
    with RawConnection(bridge.port) as client:
        for _ in range(3):
            client.command("__subscribe", topic=topic, message_name="std_msgs/String", queue_size=1, added_later=True)
        client.command("__ping", request_time=request_time)
        answer = client.wait_command("__ping_response")
        assert answer["request_time"] == request_time and abs(answer["ros_time"] - time.time()) < 5
        client.sync()
        wait_subscribers(publisher)
        publisher.publish(String("hello"))
        frame = client.wait_frame(lambda f: f.destination == topic, f"message on {topic}")
        assert frame.payload == serialize(String("hello"))
        assert not client.errors()
        warnings = [json.loads(f.payload)["text"] for f in client.received if f.destination == "__warn"]
        assert warnings == ["__subscribe: field(s) 'added_later' not known to this endpoint, ignored"]
    publisher.unregister()


def test_the_tcp_client_pings_and_estimates_its_offset_to_ros_time(bridge) -> None:
    with tcp_client(bridge.port) as client:
        result = client.ping(timeout=5)
        assert 0 < result.round_trip_s < 5
        # Same machine, ROS time = wall time: the offset is within the round trip (plus rounding).
        assert result.ros_clock_offset_s is not None and abs(result.ros_clock_offset_s) < result.round_trip_s + 0.01
        assert client.errors == []


def test_a_client_gets_the_others_messages_on_a_topic_it_publishes_but_not_its_own(bridge, ros_node) -> None:
    """Unity's users asked for this (ROS-TCP-Endpoint PR #159): a client that publishes and subscribes on a topic is
    not sent its own messages back, while every other message on the topic reaches it."""
    topic = unique("no_echo")
    own, other = Inbox(), Inbox()
    warm_up = serialize(String("warm-up"))
    with tcp_client(bridge.port) as chatty, tcp_client(bridge.port) as quiet:
        for client, inbox in ((chatty, own), (quiet, other)):
            client.subscribe(topic, "std_msgs/String", inbox)
            client.register_publisher(topic, "std_msgs/String")
            client.topic_list()

        def warmed_up() -> bool:  # the endpoint's subscriber is connected to its own publisher
            chatty.publish(topic, warm_up)
            return warm_up in other.snapshot()

        wait_for(warmed_up, 10, "a message from one client at the other", interval=0.1)
        ros_publisher = ros_node.Publisher(topic, String, queue_size=10)
        wait_subscribers(ros_publisher)
        for index in range(20):
            chatty.publish(topic, serialize(String(f"chatty {index}")))
            quiet.publish(topic, serialize(String(f"quiet {index}")))
        ros_publisher.publish(String("from ros"))
        expected_own = {serialize(String(f"quiet {i}")) for i in range(20)} | {serialize(String("from ros"))}
        expected_other = {serialize(String(f"chatty {i}")) for i in range(20)} | {serialize(String("from ros"))}
        wait_for(
            lambda: expected_own <= set(own.snapshot()) and expected_other <= set(other.snapshot()),
            10,
            "every other client's message at each client",
        )
        chatty.topic_list()
        quiet.topic_list()  # anything else in flight has arrived by now
        assert set(own.snapshot()) == expected_own and len(own) == 21  # none of its own, not even a warm-up
        assert set(other.snapshot()) - {warm_up} == expected_other
        ros_publisher.unregister()


def test_an_endpoint_configured_so_sends_clients_their_own_messages_back(roscore, ros_node, tmp_path) -> None:
    topic = unique("echo_on")
    process = start_endpoint(roscore, tmp_path, "--echo-own-publications")
    try:
        own = Inbox()
        with tcp_client(process.port) as client:
            client.subscribe(topic, "std_msgs/String", own)
            client.register_publisher(topic, "std_msgs/String")
            client.topic_list()
            message = serialize(String("mine"))

            def echoed() -> bool:
                client.publish(topic, message)
                return message in own.snapshot()

            wait_for(echoed, 10, "its own message back", interval=0.1)
    finally:
        process.stop()


def test_a_subscription_with_queue_size_keeps_only_that_many_waiting_for_a_slow_client(bridge, ros_node) -> None:
    """__subscribe's queue_size is that client's queue depth for the topic: a client that does not read gets the
    newest messages when it reads again, and is told how many were dropped."""
    topic = unique("queue_size")
    publisher = ros_node.Publisher(topic, String, queue_size=1000)
    diagnostics = DiagnosticsInbox(ros_node, "/" + bridge.name)
    with RawConnection(bridge.port, rcvbuf=4096) as latest_only, RawConnection(bridge.port, rcvbuf=4096) as all_of_it:
        latest_only.command("__subscribe", topic=topic, message_name="std_msgs/String", queue_size=1)
        all_of_it.command("__subscribe", topic=topic, message_name="std_msgs/String")
        latest_only.sync()
        all_of_it.sync()
        wait_subscribers(publisher, count=1)
        # 6 MB: more than the sockets can ever hold for a client that does not read (Linux autotunes a loopback
        # connection's send buffer to its traffic, up to tcp_wmem's 4 MiB: 600 messages of 200 B all fitted once)
        sent = [serialize(String(f"sample {index:04d} " + "x" * 10_000)) for index in range(600)]
        for index in range(600):
            publisher.publish(String(f"sample {index:04d} " + "x" * 10_000))
        # neither client reads until the endpoint has handed every message to them (sent, or queued): it counts them
        # on /diagnostics
        wait_for(
            lambda: (status := diagnostics.find(topic)) and status_values(status)["messages to clients"] == "600",
            15,
            f"600 messages of {topic} handed to the clients",
        )
        latest_only.sync()
        all_of_it.sync()
        got_latest, got_all = latest_only.messages(topic), all_of_it.messages(topic)
        assert got_latest[-1] == sent[-1] and got_all[-1] == sent[-1]
        assert len(got_latest) < len(got_all) <= len(sent)
        assert got_latest == [payload for payload in sent if payload in set(got_latest)]  # in order, no duplicates
        warnings = " ".join(json.loads(f.payload)["text"] for f in latest_only.received if f.destination == "__warn")
        assert "dropped" in warnings
    diagnostics.close()
    publisher.unregister()


def test_under_use_sim_time_clients_get_clock_and_pings_answer_in_simulated_time(tmp_path) -> None:
    """With /use_sim_time, rospy subscribes to /clock in the endpoint's own process with its own class, and one
    subscription of a process has one class: a client's /clock subscription then gets decoded messages, which the
    endpoint serializes again (it used to fail on them, and the client got no /clock at all)."""
    import io
    import subprocess

    from bridge.client import TcpClient
    from tests.rosenv import EndpointProcess, RosCore

    core = RosCore()
    try:
        subprocess.run(["rosparam", "set", "/use_sim_time", "true"], env=core.env, check=True, timeout=30)
        endpoint = EndpointProcess(core.env, tmp_path)
        source, sink = TcpClient("127.0.0.1", endpoint.port), TcpClient("127.0.0.1", endpoint.port)
        received: list[bytes] = []
        try:
            source.register_publisher("/clock", "rosgraph_msgs/Clock")
            sink.subscribe("/clock", "rosgraph_msgs/Clock", received.append)
            source.connect()
            sink.connect()
            sent = io.BytesIO()
            Clock(clock=rospy.Time(1234, 500_000_000)).serialize(sent)

            def clock_seen() -> bool:
                source.publish("/clock", sent.getvalue())
                return bool(received)

            wait_for(clock_seen, 20, "/clock through the endpoint", interval=0.2)
            assert received[-1] == sent.getvalue()
            answer = sink.ping()
            assert answer.ros_clock_offset_s is not None
            assert answer.ros_clock_offset_s + time.time() == pytest.approx(1234.5, abs=0.5)  # ROS time is /clock's
        finally:
            source.close()
            sink.close()
            endpoint.stop()
    finally:
        core.stop()
