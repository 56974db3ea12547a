"""bridge.admission.room, pure: which connection makes room for a newcomer when the endpoint is full."""

from __future__ import annotations

from bridge.admission.room import (
    FRAME_GRACE_S,
    MAX_SUSPECTS,
    SILENT_GRACE_S,
    SLOW_PACE,
    SUSPECT_S,
    SlotUse,
    Suspects,
    pace,
    to_evict,
)


def use(
    connected_for_s: float = 60.0,
    frame_for_s: float | None = None,
    frame_bytes: int = 0,
    frames_completed: int = 10,
    authenticated: bool = True,
    unread_bytes: int = 0,
    suspect: bool = False,
) -> SlotUse:
    return SlotUse(connected_for_s, frame_for_s, frame_bytes, frames_completed, authenticated, unread_bytes, suspect)


def test_connections_between_whole_frames_use_their_slot_however_long_idle() -> None:
    assert pace(use(connected_for_s=3600.0)) is None
    assert to_evict([use(), use(connected_for_s=5.0)]) is None


def test_a_frame_arriving_slowly_past_the_grace_is_measured_by_its_pace() -> None:
    assert pace(use(frame_for_s=FRAME_GRACE_S / 2, frame_bytes=1)) is None  # too young to tell
    assert pace(use(frame_for_s=4.0, frame_bytes=4)) == 1.0


def test_the_slowest_sender_goes_first_then_the_longest_connected() -> None:
    camera = use(frame_for_s=1.5, frame_bytes=3_000_000)  # a large image over a slow link
    loris = use(frame_for_s=20.0, frame_bytes=20, connected_for_s=30.0)
    older_loris = use(frame_for_s=20.0, frame_bytes=20, connected_for_s=40.0)
    assert to_evict([camera, loris, use()]) == 1
    assert to_evict([camera, loris, older_loris]) == 2
    assert to_evict([camera]) is None  # a frame coming at megabytes a second uses its slot


def test_a_frame_at_a_pace_below_the_floor_is_not_using_its_slot() -> None:
    assert pace(use(frame_for_s=2.0, frame_bytes=2 * SLOW_PACE - 2)) == SLOW_PACE - 1
    assert pace(use(frame_for_s=2.0, frame_bytes=2 * SLOW_PACE)) is None


def test_no_auth_after_the_grace_or_no_frame_at_all_for_long_is_not_using_the_slot() -> None:
    assert pace(use(connected_for_s=FRAME_GRACE_S / 2, authenticated=False, frames_completed=0)) is None
    assert pace(use(connected_for_s=FRAME_GRACE_S * 2, authenticated=False, frames_completed=0)) == 0.0
    assert pace(use(connected_for_s=SILENT_GRACE_S / 2, frames_completed=0)) is None
    assert pace(use(connected_for_s=SILENT_GRACE_S * 2, frames_completed=0)) == 0.0
    silent = use(connected_for_s=SILENT_GRACE_S * 2, frames_completed=0)
    assert to_evict([use(frame_for_s=3.0, frame_bytes=30), silent]) == 1


def test_bytes_the_reader_has_not_taken_yet_count_as_sent() -> None:
    # A starved reader: the client's __auth, or its first frame, waits in the kernel past the grace.
    starved = use(connected_for_s=FRAME_GRACE_S * 2, authenticated=False, frames_completed=0, unread_bytes=40)
    assert pace(starved) is None
    assert pace(use(connected_for_s=SILENT_GRACE_S * 2, frames_completed=0, unread_bytes=8)) is None
    assert pace(use(frame_for_s=2.0, frame_bytes=2, unread_bytes=2 * SLOW_PACE)) is None
    loris = use(frame_for_s=20.0, frame_bytes=20)
    assert to_evict([starved, loris]) == 1


def test_young_connections_from_a_suspect_address_make_room_after_proven_non_users() -> None:
    young = use(connected_for_s=0.5, frame_for_s=0.4, frame_bytes=1, frames_completed=0)
    young_suspect = use(connected_for_s=0.5, frame_for_s=0.4, frame_bytes=1, frames_completed=0, suspect=True)
    older_suspect = use(connected_for_s=0.9, frames_completed=0, suspect=True)
    assert to_evict([young, young]) is None  # no evidence at all: every slot is safe
    assert to_evict([young, young_suspect, older_suspect]) == 2
    assert to_evict([young_suspect, use(frame_for_s=20.0, frame_bytes=20)]) == 1  # the proven one first
    # a client of a suspect address that uses its slot (between whole frames) is never cut
    assert to_evict([use(suspect=True), use(connected_for_s=0.2, frames_completed=3, suspect=True)]) is None


def test_an_address_stays_a_suspect_for_its_time_and_the_oldest_are_forgotten_first() -> None:
    suspects = Suspects()
    suspects.note("10.0.0.1", 100.0)
    assert suspects.is_suspect("10.0.0.1", 100.0 + SUSPECT_S)
    assert not suspects.is_suspect("10.0.0.1", 100.0 + SUSPECT_S + 0.1)
    assert not suspects.is_suspect("10.0.0.2", 100.0)
    for index in range(MAX_SUSPECTS + 1):
        suspects.note(f"10.1.{index // 256}.{index % 256}", 200.0 + index * 1e-6)
    assert not suspects.is_suspect("10.1.0.0", 201.0)  # the oldest, past the bound
    assert suspects.is_suspect(f"10.1.{MAX_SUSPECTS // 256}.{MAX_SUSPECTS % 256}", 201.0)
    assert len(suspects) <= MAX_SUSPECTS
