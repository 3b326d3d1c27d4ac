"""LZF decompression (the ``binary_compressed`` encoding of PCD files), in numba.

An LZF stream is a sequence of instructions, each starting with a control byte c:
- c < 32: a literal run; the next c + 1 bytes are copied;
- c ≥ 32: a back-reference of L + 2 bytes, L = c >> 5 (when L = 7 the next byte
  is added to it), starting ((c & 31) << 8) + (next byte) + 1 bytes back in the
  output.
Every read and write is bounds-checked, so a corrupt stream raises DecodeError.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError

__all__ = ["lzf_compress_literal", "lzf_decompress"]


@nb.njit(cache=True)
def _lzf_kernel(src: NDArray[np.uint8], dst: NDArray[np.uint8]) -> int:
    """Expand the LZF stream ``src`` into ``dst``; the bytes written, or a negative code:
    -1 the stream ends inside an instruction, -2 it expands beyond ``dst``,
    -3 a back reference points before the start of the output."""
    n_in = src.shape[0]
    n_out = dst.shape[0]
    ip = 0
    op = 0
    while ip < n_in:
        ctrl = int(src[ip])
        ip += 1
        if ctrl < 32:  # a literal run of ctrl + 1 bytes
            length = ctrl + 1
            if ip + length > n_in:
                return -1
            if op + length > n_out:
                return -2
            for k in range(length):
                dst[op + k] = src[ip + k]
            ip += length
            op += length
        else:  # a back reference: length in the top 3 bits, offset in 13 bits
            length = ctrl >> 5
            if length == 7:
                if ip >= n_in:
                    return -1
                length += int(src[ip])
                ip += 1
            if ip >= n_in:
                return -1
            ref = op - ((ctrl & 0x1F) << 8) - int(src[ip]) - 1
            ip += 1
            length += 2
            if ref < 0:
                return -3
            if op + length > n_out:
                return -2
            for k in range(length):  # byte by byte: the source may overlap the output
                dst[op + k] = dst[ref + k]
            op += length
    return op


_LZF_ERRORS = {
    -1: "the LZF stream ends inside an instruction",
    -2: "the LZF stream expands beyond its stated size",
    -3: "an LZF back reference points before the start of the data",
}


def lzf_decompress(data: bytes | NDArray[np.uint8], size: int) -> NDArray[np.uint8]:
    """Expand an LZF stream (liblzf's format) to exactly ``size`` bytes.

    Raises DecodeError if the stream is malformed or expands to another size.
    """
    src = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes) else data
    dst = np.empty(size, dtype=np.uint8)
    written = int(_lzf_kernel(src, dst))
    if written < 0:
        raise DecodeError(_LZF_ERRORS[written])
    if written != size:
        raise DecodeError(f"the LZF stream expands to {written} bytes, the header says {size}")
    return dst


def lzf_compress_literal(data: bytes) -> bytes:
    """A valid LZF stream for ``data`` made of literal runs only (no compression):
    each run is a control byte ``n - 1`` followed by ``n`` ≤ 32 bytes."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i : i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)
