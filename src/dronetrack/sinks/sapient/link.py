"""An edge node's TCP link to a SAPIENT fusion node, that never blocks the tracking loop.

A daemon thread owns the socket.  It connects, sends the Registration and waits for
the RegistrationAck; then it sends what the tracking loop queued (``send``) and reads
what the fusion node sends (its Tasks wait in ``tasks``; its Errors are said in one
line and counted).  When the fusion node goes away, sends garbage or a frame over the
limit, or closes in the middle of one, the thread says so in one line, and connects
again after a back-off that doubles up to ``backoff_s[1]``.  A fusion node that cannot
be reached, or refuses the registration, is said once until the link registers.

``send`` only queues: while the link is not registered, or when ``max_pending``
messages wait already, the message is dropped and counted (``stats.dropped``), so a
C2 system that is down costs the tracking loop nothing and no memory.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from dronetrack.errors import ConfigError, SapientProtocolError
from dronetrack.formats.sapient.framing import MAX_FRAME_BYTES, FrameDecoder, encode_frame
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.task_pb2 import Task

__all__ = ["LinkStats", "SapientLink", "parse_endpoint"]

Say = Callable[[str], None]


def parse_endpoint(text: str, option: str = "--sapient") -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:PORT`` for an IPv6 address) as (host, port);
    ``ConfigError`` in one line otherwise."""
    host, sep, port = text.rpartition(":")
    host = host.removeprefix("[").removesuffix("]")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(
            f"{option} {text!r}: give the fusion node as HOST:PORT, e.g. 127.0.0.1:5020"
        )
    return host, int(port)


@dataclass
class LinkStats:
    """What the link did: messages sent and dropped, connections made, frames it could
    not read, Error messages the fusion node sent, and its state."""

    sent: int = 0
    dropped: int = 0
    connects: int = 0
    bad_frames: int = 0
    errors: int = 0
    connected: bool = False
    registered: bool = False
    last_error: str = ""

    @property
    def reconnects(self) -> int:
        """Connections made after the first."""
        return max(0, self.connects - 1)


class SapientLink:
    """The link to ``host:port``; it starts connecting at once, in its own thread.

    ``registration()`` makes the Registration to send on each connection (fresh, with
    its time).  ``say`` is told each event in one line (from the link's thread).
    ``connect_timeout_s`` bounds a connection attempt, ``ack_timeout_s`` the wait for
    the RegistrationAck; ``backoff_s`` = (first, longest) wait between attempts [s],
    doubling from the first; ``max_pending`` messages wait to be sent at most;
    ``max_frame_bytes`` bounds a frame read from the fusion node.
    """

    def __init__(
        self,
        host: str,
        port: int,
        registration: Callable[[], SapientMessage],
        *,
        say: Say | None = None,
        connect_timeout_s: float = 1.0,
        backoff_s: tuple[float, float] = (0.25, 2.0),
        ack_timeout_s: float = 3.0,
        max_pending: int = 256,
        max_frame_bytes: int = MAX_FRAME_BYTES,
    ) -> None:
        self.host, self.port = host, port
        self.where = f"{host}:{port}"
        self.registration = registration
        self.say = say or (lambda text: None)
        self.connect_timeout_s = connect_timeout_s
        self.backoff_s = backoff_s
        self.ack_timeout_s = ack_timeout_s
        self.max_pending = max_pending
        self.max_frame_bytes = max_frame_bytes
        self.stats = LinkStats()
        self._outbox: deque[bytes] = deque()
        self._inbox: deque[Task] = deque()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._wake_r, self._wake_w = socket.socketpair()
        self._reported = ""  # the last failure said, so that an outage is one line
        self._error_said = ""  # the last Error message said, likewise
        self._thread = threading.Thread(target=self._run, name="sapient-link", daemon=True)
        self._thread.start()

    def send(self, message: SapientMessage) -> bool:
        """Queue ``message``; False (and counted as dropped) when the link is not
        registered or its queue is full.  Never blocks."""
        frame = encode_frame(message)
        with self._lock:
            if not self.stats.registered or len(self._outbox) >= self.max_pending:
                self.stats.dropped += 1
                return False
            self._outbox.append(frame)
        self._wake()
        return True

    def tasks(self) -> list[Task]:
        """The Tasks received since the last call, in order."""
        with self._lock:
            out = list(self._inbox)
            self._inbox.clear()
        return out

    def close(self, timeout_s: float = 2.0) -> None:
        """Send what is queued, then close the link; waits for the link's thread for
        ``timeout_s`` at most (the thread ends by itself within about 2 s: a stalled
        send and the orderly end of the connection are bounded by 1 s each)."""
        self._stop.set()
        self._wake()
        self._thread.join(timeout_s)

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    # ------------------------------------------------------------ the link's thread

    def _run(self) -> None:
        """Connect, register and serve, again and again, until ``close``."""
        delay = self.backoff_s[0]
        try:
            while not self._stop.is_set():
                if self._session():
                    delay = self.backoff_s[0]
                if not self._stop.is_set():
                    self._stop.wait(delay)
                    delay = min(2.0 * delay, self.backoff_s[1])
        finally:
            for sock in (self._wake_r, self._wake_w):
                sock.close()

    def _session(self) -> bool:
        """One connection, from its start to its end: True if it was registered."""
        try:
            sock = socket.create_connection((self.host, self.port), self.connect_timeout_s)
        except OSError as err:
            self._failed(f"cannot reach the fusion node at {self.where} ({_why(err)})", str(err))
            return False
        registered = False
        with sock:
            self.stats.connects += 1
            self.stats.connected = True
            try:
                decoder = FrameDecoder(self.max_frame_bytes)
                registered = self._register(sock, decoder)
                if registered:
                    self._serve(sock, decoder)
            except Exception as err:  # the thread outlives whatever one connection does
                if not self._stop.is_set():
                    if isinstance(err, SapientProtocolError):
                        self.stats.bad_frames += 1
                    self.say(f"sapient: link to {self.where} lost: {_why(err)}; reconnecting")
                    self._note(str(err))
            finally:
                with self._lock:
                    self.stats.dropped += len(self._outbox)
                    self._outbox.clear()
                    self.stats.connected = self.stats.registered = False
        return registered

    def _failed(self, text: str, error: str) -> None:
        """A connection that failed before it was registered: said once, however many
        times it fails the same way."""
        if text != self._reported:
            self.say(f"sapient: {text}; retrying every {self.backoff_s[1]:g} s at most")
            self._reported = text
        self._note(error)

    def _note(self, error: str) -> None:
        with self._lock:
            self.stats.last_error = error

    def _register(self, sock: socket.socket, decoder: FrameDecoder) -> bool:
        """Send the Registration and wait for its acknowledgement: True if accepted.
        What came after the acknowledgement in the same read is kept for ``_serve``."""
        sock.settimeout(1.0)
        sock.sendall(encode_frame(self.registration()))
        deadline = time.monotonic() + self.ack_timeout_s
        while time.monotonic() < deadline and not self._stop.is_set():
            try:
                messages = _read(sock, decoder)
            except TimeoutError:
                continue
            for i, message in enumerate(messages):
                if message.WhichOneof("content") != "registration_ack":
                    continue
                ack = message.registration_ack
                if ack.acceptance:
                    with self._lock:
                        self.stats.registered = True
                    self._reported = ""
                    self._take(messages[i + 1 :])
                    self.say(f"sapient: registered with the fusion node at {self.where}")
                    return True
                reason = "; ".join(ack.ack_response_reason) or "no reason given"
                self._failed(
                    f"the fusion node at {self.where} refused us: {reason}",
                    f"registration refused: {reason}",
                )
                return False
        if not self._stop.is_set():
            self._failed(
                f"no RegistrationAck from {self.where} in {self.ack_timeout_s:g} s",
                "no RegistrationAck",
            )
        return False

    def _serve(self, sock: socket.socket, decoder: FrameDecoder) -> None:
        """Send the queue and read the fusion node's messages until the link breaks or
        ``close``; on close, the queue is sent first, then the connection ended in
        order (``_part``)."""
        sock.setblocking(False)
        with selectors.DefaultSelector() as sel:
            sel.register(sock, selectors.EVENT_READ)
            sel.register(self._wake_r, selectors.EVENT_READ)
            while True:
                self._flush(sock)
                if self._stop.is_set():
                    self._part(sock)
                    return
                for key, _ in sel.select(timeout=0.5):
                    if key.fileobj is self._wake_r:
                        with contextlib.suppress(BlockingIOError):
                            self._wake_r.recv(4096)
                        continue
                    self._take(_read(sock, decoder))

    def _part(self, sock: socket.socket) -> None:
        """End the connection in order: the end of the stream after the last frame,
        then read until the fusion node closes too (1 s at most).  Closing with its
        answers unread would reset the connection, which can lose the last frames."""
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_WR)
            sock.settimeout(0.1)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                try:
                    if not sock.recv(65536):
                        return
                except TimeoutError:
                    continue

    def _take(self, messages: list[SapientMessage]) -> None:
        """Keep the Tasks among ``messages`` for ``tasks``, and say the fusion node's
        Errors (each new text once in a row); the rest need no answer."""
        for message in messages:
            kind = message.WhichOneof("content")
            if kind == "task":
                with self._lock:
                    self._inbox.append(message.task)
            elif kind == "error":
                self.stats.errors += 1
                text = "; ".join(message.error.error_message) or "no description"
                if text != self._error_said:
                    self.say(f"sapient: the fusion node at {self.where} reports an error: {text}")
                    self._error_said = text

    def _flush(self, sock: socket.socket) -> None:
        """Send every queued frame (blocking up to 1 s each: the link's thread waits, the
        tracking loop does not)."""
        sock.settimeout(1.0)
        try:
            while True:
                with self._lock:
                    if not self._outbox:
                        return
                    frame = self._outbox.popleft()
                try:
                    sock.sendall(frame)
                except OSError:
                    with self._lock:
                        self.stats.dropped += 1
                    raise
                with self._lock:
                    self.stats.sent += 1
        finally:
            sock.setblocking(False)


def _read(sock: socket.socket, decoder: FrameDecoder) -> list[SapientMessage]:
    """The messages one read completes; ``SapientProtocolError`` for bad bytes or an
    end inside a frame, ``ConnectionResetError`` for the fusion node's end."""
    data = sock.recv(65536)
    if not data:
        decoder.close()
        raise ConnectionResetError("the fusion node closed the connection")
    return decoder.feed(data)


def _why(err: BaseException) -> str:
    """An error in a few words: the OS's text, else the message."""
    if isinstance(err, OSError) and err.strerror:
        return err.strerror.lower()
    return str(err) or type(err).__name__
