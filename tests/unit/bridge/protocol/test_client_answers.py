"""bridge.protocol.client_answers: each answer from the endpoint goes to whoever asked for it."""

from __future__ import annotations

from bridge.protocol import Log, PingResponse, ServiceResponse, TopicList
from bridge.protocol.client_answers import Answers


def test_a_service_response_goes_to_its_call_and_no_other() -> None:
    answers = Answers()
    first, second = answers.call(101, "/a"), answers.call(102, "/b")
    assert answers.take(ServiceResponse(102, "/b", b"done"))
    assert second.done.is_set() and second.response == b"done"
    assert not first.done.is_set()
    answers.forget_call(101)
    assert answers.take(ServiceResponse(101, "/a", b"late"))  # an answer nobody waits for any more is dropped
    assert not first.done.is_set()


def test_a_call_the_endpoint_gives_up_fails_at_once_and_a_lost_connection_fails_them_all() -> None:
    answers = Answers()
    first, second, third = (answers.call(srv_id, "/s") for srv_id in (101, 102, 103))
    answers.fail_call(102, "no such service")
    assert second.done.is_set() and second.failure == "no such service" and not first.done.is_set()
    answers.fail_calls("connection lost")
    assert first.failure == third.failure == "connection lost" and first.done.is_set() and third.done.is_set()


def test_a_topic_list_answers_every_query_waiting_and_a_ping_only_its_own() -> None:
    answers = Answers()
    (done_1, result_1), (done_2, result_2) = answers.topic_list(), answers.topic_list()
    assert answers.take(TopicList(("/a",), ("std_msgs/String",)))
    assert done_1.is_set() and done_2.is_set() and result_1 == result_2 == {"/a": "std_msgs/String"}
    done, got = answers.ping("t1")
    assert answers.take(PingResponse("t0", 1.0)) and not done.is_set()
    assert answers.take(PingResponse("t1", 2.0)) and done.is_set() and got == [PingResponse("t1", 2.0)]


def test_what_is_not_an_answer_is_left_to_the_client() -> None:
    assert not Answers().take(Log("hello"))
