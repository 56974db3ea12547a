"""The book of the endpoint node's registrations with the ROS master (bridge.ros.registry): pure, no master needed."""

from __future__ import annotations

from bridge.ros.registry import Registration, RegistrationBook

PUB = Registration("publisher", "/a", "std_msgs/String")
SUB = Registration("subscriber", "/b", "std_msgs/String")
SRV = Registration("service", "/c", "rosrpc://host:1234")


def test_what_rospy_registered_before_is_owed_nothing() -> None:
    book = RegistrationBook((PUB, SUB), identity="master 1")
    assert book.to_register() == [] and book.to_unregister() == []
    assert book.counts() == {"publisher": 1, "subscriber": 1, "service": 0}


def test_a_new_registration_is_owed_until_the_master_accepts_it() -> None:
    book = RegistrationBook(identity="master 1")
    book.add(SRV)
    book.add(SUB)
    book.add(PUB)
    assert book.to_register() == [PUB, SUB, SRV]  # publishers first, then subscribers, then services
    book.registered(SUB)
    assert book.to_register() == [PUB, SRV]


def test_another_master_is_owed_everything_again_and_nothing_to_take_back() -> None:
    book = RegistrationBook((PUB, SUB, SRV), identity="master 1")
    book.remove(SUB)
    assert book.to_unregister() == [SUB]
    assert book.master_is("master 1") is False
    assert book.master_is("master 2") is True
    assert book.to_register() == [PUB, SRV] and book.to_unregister() == []


def test_the_first_master_seen_is_not_a_restart() -> None:
    book = RegistrationBook((PUB,))
    assert book.master_is("master 1") is False
    assert book.to_register() == [PUB]  # identity unknown until now: nothing counts as held


def test_withdrawn_before_the_master_accepted_it_is_taken_back_after() -> None:
    book = RegistrationBook(identity="master 1")
    book.add(PUB)
    (owed,) = book.to_register()
    book.remove(PUB)  # while the registration call is on its way
    book.registered(owed)
    assert book.to_unregister() == [PUB] and book.to_register() == []
    book.unregistered(PUB)
    assert book.to_unregister() == []


def test_withdrawn_and_added_again_is_taken_back_then_registered() -> None:
    book = RegistrationBook((SRV,), identity="master 1")
    moved = Registration("service", "/c", "rosrpc://host:5678")  # the service made again: another URI
    book.remove(SRV)
    book.add(moved)
    assert book.to_unregister() == [SRV] and book.to_register() == [moved]


def test_a_registration_replaced_while_on_its_way_leaves_the_new_one_owed() -> None:
    book = RegistrationBook(identity="master 1")
    book.add(SRV)
    (owed,) = book.to_register()
    moved = Registration("service", "/c", "rosrpc://host:5678")
    book.remove(SRV)
    book.add(moved)
    book.registered(owed)
    assert book.to_unregister() == [SRV] and book.to_register() == [moved]
    assert len(book) == 1
