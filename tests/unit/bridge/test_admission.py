"""bridge.admission, pure: which connection makes room for a newcomer when the endpoint is full."""

from __future__ import annotations

from bridge.admission import FRAME_GRACE_S, SILENT_GRACE_S, SLOW_PACE, SlotUse, pace, to_evict


def use(
    connected_for_s: float = 60.0,
    frame_for_s: float | None = None,
    frame_bytes: int = 0,
    frames_completed: int = 10,
    authenticated: bool = True,
) -> SlotUse:
    return SlotUse(connected_for_s, frame_for_s, frame_bytes, frames_completed, authenticated)


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
