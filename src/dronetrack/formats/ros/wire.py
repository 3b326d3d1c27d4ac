"""Reading ROS message bytes: a bounds-checked cursor for CDR (ROS 2) and ROS 1
serialisation, shared by the point-message decoders.

CDR (ROS 2) starts with a 4-byte encapsulation header (00 01 little-endian,
00 00 big-endian); every primitive of n bytes is aligned to a multiple of n
counted from the end of that header; a string is a uint32 length that counts
its closing NUL, then the bytes.  ROS 1 is little-endian with no alignment and
strings without a NUL.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError

__all__ = ["ByteCursor", "as_byte_view", "decode_string"]


class ByteCursor:
    """A cursor over message bytes that raises DecodeError on truncation."""

    __slots__ = ("buf", "order", "origin", "pos", "what")

    def __init__(
        self, buf: memoryview, pos: int, order: Literal["little", "big"], origin: int, what: str
    ) -> None:
        self.buf, self.pos, self.order, self.origin, self.what = buf, pos, order, origin, what

    def align(self, size: int) -> None:
        # CDR: a primitive of `size` bytes starts at a multiple of `size` after `origin`
        self.pos += -(self.pos - self.origin) % size

    def take(self, n: int, name: str) -> memoryview:
        end = self.pos + n
        if n < 0 or end > len(self.buf):
            raise DecodeError(
                f"{self.what} truncated in {name}: needs {end} bytes, has {len(self.buf)}"
            )
        out = self.buf[self.pos : end]
        self.pos = end
        return out

    def uint(self, size: int, name: str, signed: bool = False) -> int:
        return int.from_bytes(self.take(size, name), self.order, signed=signed)


def as_byte_view(raw: bytes | bytearray | memoryview | NDArray[np.uint8]) -> memoryview:
    """``raw`` as a flat, contiguous memoryview of unsigned bytes."""
    if isinstance(raw, np.ndarray):
        if raw.dtype.itemsize != 1:
            raise DecodeError(f"a message must be bytes, got an array of {raw.dtype}")
        return memoryview(np.ascontiguousarray(raw).reshape(-1).view(np.uint8).data)
    try:
        view = memoryview(raw)
    except TypeError as exc:
        raise DecodeError(f"a message is not a byte buffer: {exc}") from exc
    if not view.c_contiguous:
        view = memoryview(bytes(view))
    return view if view.format == "B" and view.ndim == 1 else view.cast("B")


def decode_string(data: memoryview, nul_terminated: bool, what: str) -> str:
    """Decode a string's bytes; CDR strings end with one NUL, counted in their length.
    ``what`` names the message in the error."""
    raw = bytes(data)
    if nul_terminated and raw:
        if raw[-1] != 0:
            raise DecodeError(f"{what} string is not NUL-terminated")
        raw = raw[:-1]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DecodeError(f"{what} string is not UTF-8: {exc}") from exc
