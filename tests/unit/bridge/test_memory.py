"""bridge.memory: when the endpoint gives freed memory back (QuietTrim, pure), and that giving it back works."""

from __future__ import annotations

from bridge.memory import QuietTrim, give_back_free_memory


def test_memory_goes_back_in_the_first_quiet_period_after_traffic() -> None:
    trim = QuietTrim(quiet_bytes=100)
    assert not trim.due(0)  # nothing moved yet: nothing to give back
    assert not trim.due(500)  # a busy period
    assert not trim.due(900)
    assert trim.due(950)  # quiet now, after 950 bytes moved
    assert not trim.due(960)  # still quiet: given back already, little moved since


def test_light_steady_traffic_gives_memory_back_once_per_quiet_bytes_moved() -> None:
    trim = QuietTrim(quiet_bytes=100)
    dues = [trim.due(total) for total in range(30, 601, 30)]  # 30 bytes a period: always quiet
    assert dues.count(True) == 5 and dues[3]  # at 120, 240, 360, 480, 600


def test_giving_memory_back_is_harmless_when_there_is_none() -> None:
    give_back_free_memory()
    give_back_free_memory()
