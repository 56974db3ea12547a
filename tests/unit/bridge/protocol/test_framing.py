"""bridge.protocol.framing, pure: frames out of any split of a stream (FrameDecoder), and every length checked
against its limit before anything is allocated."""

from __future__ import annotations

import struct
import tracemalloc
from typing import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge import protocol
from bridge.protocol import (
    Conversation,
    FrameDecoder,
    FramingError,
    InvalidInput,
    LocalProtocolError,
    ProtocolError,
    RemoteProtocolError,
    Role,
    encode_frame,
)
from bridge.protocol.framing import LARGE_PAYLOAD_BYTES
from measuring.frames import BadFrame, Frame, feed


def u32(value: int) -> bytes:
    return struct.pack("<I", value)


def raw_frame(destination: bytes, payload: bytes) -> bytes:
    return u32(len(destination)) + destination + u32(len(payload)) + payload


def feed_in_pieces(
    decoder: FrameDecoder, stream: bytes, cuts: list[int], after_each: Callable[[int, list], None] | None = None
) -> list:
    """The frames of `stream` fed cut at `cuts`; `after_each(fed, items)` is called after every feed."""
    items: list = []
    start = 0
    for cut in sorted(set(cuts)) + [len(stream)]:
        items += feed(decoder, stream[start:cut])
        start = cut
        if after_each is not None:
            after_each(cut, items)
    return items


# --- framing: property tests ----------------------------------------------------------------------------------

# Destinations as a real client writes them: UTF-8, no trailing NUL (those are stripped), within the 1 KiB limit.
destinations = st.text(st.characters(blacklist_categories=("Cs",)), max_size=40).filter(
    lambda text: not text.endswith("\0")
)
frames_strategy = st.lists(st.builds(Frame, destinations, st.binary(max_size=300)), min_size=1, max_size=25)


@settings(max_examples=300, deadline=None)
@given(frames=frames_strategy, data=st.data())
def test_any_split_of_a_stream_decodes_to_the_same_frames(frames: list[Frame], data) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=60))
    decoder = FrameDecoder()
    assert feed_in_pieces(decoder, stream, cuts) == frames
    assert decoder.buffered_bytes == 0


@settings(max_examples=40, deadline=None)
@given(frames=frames_strategy)
def test_one_byte_at_a_time_and_all_at_once_agree(frames: list[Frame]) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    one_by_one = FrameDecoder()
    items = []
    for index in range(len(stream)):
        items += feed(one_by_one, stream[index : index + 1])
    assert items == frames
    assert feed(FrameDecoder(), stream) == frames


@settings(max_examples=100, deadline=None)
@given(frames=frames_strategy, data=st.data())
def test_incomplete_tail_stays_buffered_until_completed(frames: list[Frame], data) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    cut = data.draw(st.integers(0, len(stream) - 1))
    decoder = FrameDecoder()
    first = feed(decoder, stream[:cut])
    assert first == frames[: len(first)] and len(first) < len(frames)
    assert first + feed(decoder, stream[cut:]) == frames


# Payloads of LARGE_PAYLOAD_BYTES and more are collected piece by piece: the same frames, whatever the split.
large_frames_strategy = st.lists(
    st.builds(
        Frame,
        st.sampled_from(["/camera/image", "/cloud", "/joint_states"]),
        st.one_of(
            st.binary(max_size=50),
            st.integers(LARGE_PAYLOAD_BYTES - 2, LARGE_PAYLOAD_BYTES + 3000).map(
                lambda size: bytes(range(256)) * (size // 256) + b"x" * (size % 256)
            ),
        ),
    ),
    min_size=1,
    max_size=6,
)


@settings(max_examples=60, deadline=None)
@given(frames=large_frames_strategy, data=st.data())
def test_large_payloads_decode_the_same_whatever_the_split(frames: list[Frame], data) -> None:
    stream = b"".join(encode_frame(frame.destination, frame.payload) for frame in frames)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=30))
    decoder = FrameDecoder()

    def counts_what_is_incomplete(fed: int, items: list) -> None:
        complete = sum(len(encode_frame(frame.destination, frame.payload)) for frame in items)
        assert decoder.buffered_bytes == fed - complete  # what the partial-frame budget counts

    items = feed_in_pieces(decoder, stream, cuts, counts_what_is_incomplete)
    assert items == frames and all(type(frame.payload) is bytes for frame in items)
    assert decoder.buffered_bytes == 0


def test_a_large_payload_over_the_limit_is_refused_before_it_arrives() -> None:
    decoder = FrameDecoder(max_payload_bytes=LARGE_PAYLOAD_BYTES)
    header = u32(3) + b"/im" + u32(LARGE_PAYLOAD_BYTES + 1)
    with pytest.raises(FramingError, match="exceeds the limit"):
        feed(decoder, header)


def test_keepalive_is_eight_zero_bytes_and_recognised() -> None:
    assert protocol.KEEPALIVE_FRAME == b"\0" * 8
    (frame,) = feed(FrameDecoder(), b"\0" * 8)
    assert frame == Frame("", b"") and frame.is_keepalive and not frame.is_syscommand
    assert not Frame("", b"x").is_keepalive
    assert Frame("__subscribe", b"{}").is_syscommand and not Frame("/t", b"").is_syscommand


def test_trailing_nuls_in_destinations_are_stripped() -> None:
    stream = raw_frame(b"/joint_states\0\0", b"abc") + raw_frame(b"__topic_list\0", b"{}")
    assert feed(FrameDecoder(), stream) == [Frame("/joint_states", b"abc"), Frame("__topic_list", b"{}")]


def test_non_utf8_destination_is_a_bad_frame_and_the_stream_continues() -> None:
    decoder = FrameDecoder()
    stream = raw_frame(b"/bad\xff\xfe", b"payload") + encode_frame("/good", b"ok")
    bad, good = feed(decoder, stream)
    assert isinstance(bad, BadFrame) and "UTF-8" in bad.reason and "bad" in bad.reason
    assert good == Frame("/good", b"ok")
    assert feed(decoder, encode_frame("/next", b"")) == [Frame("/next", b"")]


# --- framing: limits before allocation ------------------------------------------------------------------------


def test_huge_payload_length_fails_as_soon_as_the_header_is_complete_without_allocating() -> None:
    header = u32(5) + b"/huge" + u32(0xFFFFFFF0)
    decoder = FrameDecoder()
    tracemalloc.start()
    try:
        for byte in header[:-1]:
            assert feed(decoder, bytes([byte])) == []
        with pytest.raises(FramingError) as raised:
            feed(decoder, header[-1:])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20, f"decoder allocated {peak} bytes for a refused frame"
    message = str(raised.value)
    assert str(0xFFFFFFF0) in message and "/huge" in message and "limit" in message


def test_payload_limit_is_configurable_and_exact() -> None:
    decoder = FrameDecoder(max_payload_bytes=10)
    assert feed(decoder, encode_frame("/t", b"x" * 10)) == [Frame("/t", b"x" * 10)]
    with pytest.raises(FramingError, match="11"):
        feed(decoder, u32(2) + b"/t" + u32(11))


def test_oversized_destination_fails_on_its_length_prefix_alone() -> None:
    decoder = FrameDecoder()
    prefix = u32(protocol.MAX_DESTINATION_BYTES + 1)
    assert feed(decoder, prefix[:3]) == []
    with pytest.raises(FramingError, match="destination length 1025"):
        feed(decoder, prefix[3:])  # only the 4-byte prefix has arrived


def test_destination_exactly_at_the_limit_is_accepted() -> None:
    destination = "/" + "d" * (protocol.MAX_DESTINATION_BYTES - 1)
    assert feed(FrameDecoder(), encode_frame(destination, b"")) == [Frame(destination, b"")]


def test_decoder_refuses_input_after_a_framing_error() -> None:
    decoder = FrameDecoder(max_payload_bytes=4)
    with pytest.raises(FramingError):
        feed(decoder, encode_frame("/t", b"12345"))
    assert decoder.buffered_bytes == 0
    with pytest.raises(FramingError):
        feed(decoder, encode_frame("/t", b"ok"))
    with pytest.raises(FramingError):
        feed(decoder, b"")


def test_a_lost_stream_keeps_nothing_it_had_received() -> None:
    """The error that ends a stream is kept (and raised again), but not its traceback: that would keep the frame
    being read and the buffer with it (up to the payload limit) alive with the connection's objects."""
    import gc
    import weakref

    conversation = Conversation(Role.ENDPOINT, max_payload_bytes=1 << 20)
    conversation.receive_data(encode_frame("/t", b"x" * 4096)[:-1])  # a partial frame in the buffer
    *_, lost = conversation.receive_data(b"x" + b"\xff" * 16)  # then a length far over the limit
    assert isinstance(lost, InvalidInput) and lost.error.fatal and lost.error.__traceback__ is None
    assert conversation.buffered_bytes == 0
    watched = weakref.ref(conversation)
    gc.disable()  # freed by reference counting alone, at once: nothing refers back to it
    try:
        del conversation, lost
        assert watched() is None
    finally:
        gc.enable()


def test_framing_error_is_a_fatal_remote_protocol_error() -> None:
    assert issubclass(FramingError, RemoteProtocolError) and issubclass(RemoteProtocolError, ProtocolError)
    assert issubclass(LocalProtocolError, ProtocolError) and issubclass(ProtocolError, ValueError)
    assert FramingError("x").fatal and not RemoteProtocolError("x").fatal
