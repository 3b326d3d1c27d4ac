"""The line to a FLIR pan-tilt unit: a serial port (pyserial) or a TCP socket, run one
transaction at a time.

A transaction writes one or more commands in one write (``PP TP `` reads both
positions) and reads one reply line per command (``formats.ptu.parse_reply``; lines
without a reply, an echo or a lone ``!P``, are skipped and the limit markers
counted).  A lock is held for the whole exchange, so the poller's reads and a
frame's command never interleave.  Before it writes, the transaction throws away
whatever is waiting (a late reply, an asynchronous ``!P``); after a reply that
never came, it first waits for the line to fall quiet, so a late answer is not
taken for the next one's.

Errors.  A reply ``! message`` raises DeviceError naming the unit, the command and
the message; no complete answer within ``REPLY_TIMEOUT_S`` plus the bytes' time on
the line raises DeviceError naming the unit, what was asked and, on a serial line,
the baud rate tried; so does a line that
fails (unplugged adapter, connection reset).

When the unit saw a command.  A serial byte takes 10/baud seconds (8N1), so the
unit has a command whole once the bytes up to its delimiter have crossed the line:
t_k = t_write + n_k · 10 / baud, with n_k the bytes written up to and including
command k's delimiter (the USB adapter adds up to a millisecond).  Over TCP, with
no such model, t_k is the middle of the exchange.  ``Exchange.seen`` holds t_k:
a position query's answer is the position then.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from dronetrack.actuators.ptu.uri import PtuUri
from dronetrack.errors import DeviceError, MissingExtraError
from dronetrack.formats.ptu import Reply, byte_time, parse_reply, split_lines

__all__ = [
    "IO_ERRORS",
    "REPLY_TIMEOUT_S",
    "Exchange",
    "PtuLine",
    "SerialTransport",
    "TcpTransport",
    "Transport",
    "open_line",
]

REPLY_TIMEOUT_S = 0.15  # beyond the bytes' own time on the line
CONNECT_TIMEOUT_S = 3.0
QUIET_S = 0.02  # after a missed reply: the line is quiet once this passes with no byte
DRAIN_MAX_S = 0.5
_REPLY_BYTES = 12  # a typical reply's length, for the time-out of a transaction


def _io_errors() -> tuple[type[BaseException], ...]:
    """What a failing line raises: OSError (pyserial's SerialException and socket errors
    are ones) and, on POSIX, termios.error (not an OSError)."""
    try:
        import termios
    except ImportError:
        return (OSError,)
    return (OSError, termios.error)


IO_ERRORS = _io_errors()


class Transport(Protocol):
    """Bytes to and from the unit."""

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """What has arrived, waiting up to ``timeout_s`` for the first byte (b"" if none)."""
        ...

    def discard_input(self) -> None: ...

    def close(self) -> None: ...


class SerialTransport:
    """A serial port at ``baud``, 8N1, no flow control (pyserial, ``dronetrack[live]``)."""

    def __init__(self, device: str, baud: int) -> None:
        try:
            import serial
        except ImportError as exc:
            raise MissingExtraError(
                "the FLIR PTU on a serial line needs pyserial: pip install 'dronetrack[live]'"
            ) from exc
        self.port: Any = serial.Serial(
            device,
            baudrate=baud,
            bytesize=serial.EIGHTBITS,
            parity=serial.PARITY_NONE,
            stopbits=serial.STOPBITS_ONE,
            timeout=0,
            write_timeout=2.0,
        )

    def write(self, data: bytes) -> None:
        self.port.write(data)

    def read(self, timeout_s: float) -> bytes:
        port = self.port
        if not port.in_waiting:
            # wait in select, not spinning: the interpreter is free meanwhile
            with contextlib.suppress(ValueError):
                select.select([port.fileno()], [], [], max(timeout_s, 0.0))
        return bytes(port.read(port.in_waiting or 1))

    def discard_input(self) -> None:
        self.port.reset_input_buffer()

    def close(self) -> None:
        self.port.close()


class TcpTransport:
    """A TCP connection to ``host``:``port`` (the E Series' Ethernet port)."""

    def __init__(self, host: str, port: int, connect_timeout_s: float = CONNECT_TIMEOUT_S) -> None:
        self.sock = socket.create_connection((host, port), timeout=connect_timeout_s)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.setblocking(False)

    def write(self, data: bytes) -> None:
        self.sock.setblocking(True)
        try:
            self.sock.sendall(data)
        finally:
            self.sock.setblocking(False)

    def read(self, timeout_s: float) -> bytes:
        ready, _, _ = select.select([self.sock], [], [], max(timeout_s, 0.0))
        if not ready:
            return b""
        data = self.sock.recv(4096)
        if not data:
            raise ConnectionResetError("the unit closed the connection")
        return data

    def discard_input(self) -> None:
        while True:
            try:
                data = self.sock.recv(4096)
            except BlockingIOError:
                return
            if not data:
                raise ConnectionResetError("the unit closed the connection")

    def close(self) -> None:
        self.sock.close()


@dataclass(frozen=True, slots=True)
class Exchange:
    """One transaction: the replies, in the commands' order, the clock's time before the
    write and after the last reply, and when the unit had each command (see the
    module docstring)."""

    replies: list[Reply]
    sent: float
    done: float
    seen: list[float]


class PtuLine:
    """An open line to one unit (see the module docstring).  ``name`` names it in errors;
    ``baud`` (None over TCP) times its bytes; ``clock`` stamps the exchanges.
    Counters: ``limit_hits`` (``!P``/``!T`` seen), ``timeouts``."""

    def __init__(
        self,
        transport: Transport,
        name: str,
        *,
        baud: int | None = None,
        clock: Callable[[], float] = time.monotonic,
        timeout_s: float = REPLY_TIMEOUT_S,
    ) -> None:
        self.transport = transport
        self.name = name
        self.baud = baud
        self.clock = clock
        self.timeout_s = timeout_s
        self.lock = threading.RLock()
        self.limit_hits = 0
        self.timeouts = 0
        self.closed = False
        self._dirty = False

    @property
    def byte_s(self) -> float:
        """Seconds a byte takes on the line (0 over TCP)."""
        return byte_time(self.baud) if self.baud else 0.0

    def interrupt(self) -> None:
        """Send a bare delimiter (it ends whatever a previous host left half-typed on the
        unit), let its answer come and throw it away."""
        with self.lock:
            try:
                self.transport.write(b" ")
                time.sleep(QUIET_S + 3 * self.byte_s)
                self.transport.discard_input()
            except IO_ERRORS as exc:
                raise DeviceError(f"{self.name}: {exc}") from exc

    def transact(self, commands: Sequence[str], what: str) -> Exchange:
        """Send ``commands`` (each followed by a space) in one write and read a reply to
        each; DeviceError on a refusal, a time-out or a failing line."""
        data = "".join(f"{c} " for c in commands).encode("ascii")
        with self.lock:
            if self.closed:
                raise DeviceError(f"{self.name}: {what}: the line is closed")
            try:
                if self._dirty:
                    self._drain()
                self.transport.discard_input()
                sent = self.clock()
                self.transport.write(data)
                replies = self._replies(len(commands), len(data), what)
            except IO_ERRORS as exc:
                raise DeviceError(f"{self.name}: {what}: {exc}") from exc
            done = self.clock()
        for command, reply in zip(commands, replies, strict=True):
            if not reply.ok:
                raise DeviceError(f"{self.name}: {command}: the unit answered ! {reply.message}")
        if self.baud:
            ends = [len(" ".join(commands[: k + 1])) + 1 for k in range(len(commands))]
            seen = [sent + n * self.byte_s for n in ends]
        else:
            seen = [0.5 * (sent + done)] * len(commands)
        return Exchange(replies, sent, done, seen)

    def _replies(self, count: int, written: int, what: str) -> list[Reply]:
        limit = self.timeout_s + (written + _REPLY_BYTES * count) * self.byte_s
        deadline = time.monotonic() + limit
        replies: list[Reply] = []
        buffer = b""
        while True:
            lines, buffer = split_lines(buffer)
            for line in lines:
                reply = parse_reply(line)
                hits = reply.limit_hits if reply is not None else line.strip()
                self.limit_hits += hits.count("!P") + hits.count("!T")
                if reply is not None and len(replies) < count:
                    replies.append(reply)
            if len(replies) >= count:
                return replies
            left = deadline - time.monotonic()
            if left <= 0:
                self._dirty = True
                self.timeouts += 1
                got = f" ({len(replies)} of {count} replies)" if replies else ""
                at = f" at {self.baud} baud" if self.baud else ""
                raise DeviceError(f"{self.name}: {what}: no answer{at} within {limit:.2f} s{got}")
            buffer += self.transport.read(left)

    def _drain(self) -> None:
        """Read until the line has been quiet for ``QUIET_S`` (at most ``DRAIN_MAX_S``)."""
        end = time.monotonic() + DRAIN_MAX_S
        quiet = QUIET_S + 5 * self.byte_s
        while time.monotonic() < end and self.transport.read(quiet):
            pass
        self._dirty = False

    def close(self) -> None:
        """Close the line (waiting for a transaction under way); safe to call twice."""
        with self.lock:
            if self.closed:
                return
            self.closed = True
            with contextlib.suppress(*IO_ERRORS):
                self.transport.close()


def open_line(
    where: PtuUri, clock: Callable[[], float] = time.monotonic, timeout_s: float = REPLY_TIMEOUT_S
) -> PtuLine:
    """The line ``where`` names, open; DeviceError naming the unit if it cannot be."""
    try:
        if where.device is not None:
            transport: Transport = SerialTransport(where.device, where.baud)
            baud: int | None = where.baud
        else:
            transport = TcpTransport(str(where.host), int(where.port or 0))
            baud = None
    except IO_ERRORS as exc:
        raise DeviceError(f"{where.name}: cannot open the line: {exc}") from exc
    return PtuLine(transport, where.name, baud=baud, clock=clock, timeout_s=timeout_s)
