"""A ``SapientMessage`` on a TCP stream: its serialised bytes after their length, a
4-byte little-endian unsigned integer.

This is the framing of dstl's Apex SAPIENT middleware (github.com/dstl/
Apex-SAPIENT-Middleware, commit 0c8591ae97f2dc336eff299845880d5c73ee75b7):
``sapient_apex_server/message_io.py`` (``encode_binary``) writes
``struct.pack("<I", len(bytes)) + bytes``, and ``sapient_apex_server/trio_util.py``
(``receive_size_prefixed``) reads the 4-byte little-endian size first and refuses a
message longer than its limit, ``messageMaxSizeKb`` × 1024 bytes
(``sapient_apex_server/apex_server.py``; 1024 in its ``apex_config.json``), as
``FrameDecoder`` does here.  Apex's ``.proto`` files are vendored from the same commit.
"""

from __future__ import annotations

import struct

from google.protobuf.message import DecodeError as ProtobufDecodeError

from dronetrack.errors import SapientProtocolError
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = ["DEFAULT_PORT", "MAX_FRAME_BYTES", "FrameDecoder", "encode_frame", "parse_message"]

MAX_FRAME_BYTES = 1024 * 1024  # 1 MiB: Apex's messageMaxSizeKb = 1024
# The port Apex's apex_config.json gives BSI Flex 335 v2.0 edge nodes: its "Child"
# connection with "format": "PROTO", "icd_version": "BSI Flex 335 v2.0"
DEFAULT_PORT = 5020
_PREFIX = struct.Struct("<I")


def encode_frame(message: SapientMessage) -> bytes:
    """``message`` framed for the stream: len(b) as "<I", then b."""
    body: bytes = message.SerializeToString()
    return _PREFIX.pack(len(body)) + body


def parse_message(body: bytes) -> SapientMessage:
    """The ``SapientMessage`` in one frame's body; ``SapientProtocolError`` if it does
    not parse, or holds no content (none of registration, detection_report, ...)."""
    message = SapientMessage()
    try:
        message.ParseFromString(body)
    except ProtobufDecodeError as err:
        raise SapientProtocolError(
            f"a {len(body)}-byte frame is no SapientMessage ({err})"
        ) from None
    if message.WhichOneof("content") is None:
        raise SapientProtocolError(f"a {len(body)}-byte SapientMessage has no content")
    return message


class FrameDecoder:
    """Messages out of a byte stream fed in pieces of any size (``feed``).

    ``max_bytes`` bounds a frame's body (default ``MAX_FRAME_BYTES``, 1 MiB, Apex's
    default limit): a longer length prefix is refused at once (before its bytes
    arrive), so a peer cannot make it buffer without bound.  ``pending`` says whether
    a frame is begun; ``close`` at the stream's end refuses half a frame.
    """

    def __init__(self, max_bytes: int = MAX_FRAME_BYTES) -> None:
        if max_bytes < 1:
            raise ValueError(f"max_bytes = {max_bytes}: a frame needs room for a message")
        self.max_bytes = max_bytes
        self._buffer = bytearray()

    @property
    def pending(self) -> int:
        """Bytes of a frame begun and not finished."""
        return len(self._buffer)

    def feed(self, data: bytes) -> list[SapientMessage]:
        """The messages that ``data`` completes, in order; ``SapientProtocolError`` for
        a frame over the limit or one that does not parse (the stream is then lost:
        its framing cannot be trusted)."""
        self._buffer += data
        out = []
        while len(self._buffer) >= _PREFIX.size:
            (size,) = _PREFIX.unpack_from(self._buffer)
            if size > self.max_bytes:
                raise SapientProtocolError(
                    f"a frame of {size} bytes is over the limit of {self.max_bytes}"
                )
            end = _PREFIX.size + size
            if len(self._buffer) < end:
                break
            body = bytes(self._buffer[_PREFIX.size : end])
            del self._buffer[:end]
            out.append(parse_message(body))
        return out

    def close(self) -> None:
        """The stream ended: ``SapientProtocolError`` if it ended inside a frame."""
        if self._buffer:
            n = len(self._buffer)
            self._buffer.clear()
            raise SapientProtocolError(f"the connection closed {n} bytes into a frame")
