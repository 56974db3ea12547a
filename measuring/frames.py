"""Frames as a raw client (a test, a bench) reads them: the decoder's raw frames with their destinations decoded
(the endpoint itself never needs more than bridge.protocol.framing.FrameDecoder.feed_raw)."""

from __future__ import annotations

from dataclasses import dataclass

from bridge.protocol.framing import FrameDecoder, decode_destination, not_utf8


@dataclass(frozen=True)
class Frame:
    """One frame as it is on the wire."""

    destination: str
    payload: bytes

    @property
    def is_keepalive(self) -> bool:
        return self.destination == "" and not self.payload

    @property
    def is_syscommand(self) -> bool:
        return self.destination.startswith("__")


@dataclass(frozen=True)
class BadFrame:
    """A frame whose framing was intact but whose destination is not UTF-8."""

    reason: str


def feed(decoder: FrameDecoder, data: bytes) -> list[Frame | BadFrame]:
    """The complete frames `data` finishes, destinations decoded; raises the FramingError that ended the stream."""
    frames, failure = decoder.feed_raw(data)
    if failure is not None:
        raise failure
    decoded: list[Frame | BadFrame] = []
    for raw_destination, payload in frames:
        try:
            decoded.append(Frame(decode_destination(raw_destination), payload))
        except UnicodeDecodeError:
            decoded.append(BadFrame(not_utf8(raw_destination)))
    return decoded
