"""The emulated pan-tilt unit (``ptu.EmulatedPtu``) on a line: a pseudo-terminal paced
like a serial line at a baud rate, or a TCP server.

Pacing.  A pseudo-terminal moves bytes at once; a serial line at b baud moves one
byte every τ = 10 / b seconds (8N1).  ``LineTiming`` puts that delay back in both
directions:

* in: bytes read at time τ_r arrive one by one, from when the line is free,
  a_k = max(τ_r, a_prev) + (k + 1) τ, so a command is whole (and answered, its
  position read) at its delimiter's arrival;
* out: a reply of n bytes starts when the command is whole and the line out is
  free, and is written whole when its last byte would have arrived,
  d = max(a, d_prev) + n τ.

So ``PP TP `` at 9600 baud has the pan query whole 3.1 ms after the write, the
tilt one at 6.3 ms, and their replies back at about 13.5 and 23.5 ms: what the
host sees of a unit at that rate.  Over TCP there is no pacing (replies go as soon
as their command is whole).

Speed.  On the pseudo-terminal the unit hears only a host whose line is set to its
rate (``pty_link``): bytes written at another speed are dropped unanswered, as a real
unit's would be noise to it.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading
import time
from collections import deque
from pathlib import Path
from typing import Self

from dronetrack.errors import DeviceError
from dronetrack.formats.ptu import DEFAULT_BAUD, CommandSplitter, byte_time
from dronetrack.sim.emulate.ptu import EmulatedPtu
from dronetrack.sim.emulate.pty_link import PtyLink

__all__ = ["LineTiming", "PtyPtuLink", "TcpPtuServer"]


class LineTiming:
    """One session of the unit on a line (see the module docstring): ``receive`` the
    bytes read at a time, then ``step`` answers the commands whole by then and
    returns the replies due; ``next_due`` says when to step again.  Times are
    ``time.monotonic``'s; ``baud`` None: no pacing (each command answered at the
    unit's clock's now)."""

    def __init__(self, ptu: EmulatedPtu, baud: int | None) -> None:
        self.ptu = ptu
        self.byte_s = byte_time(baud) if baud else 0.0
        self.splitter = CommandSplitter()
        self._in_free = 0.0  # when the last byte received so far arrives
        self._out_free = 0.0  # when the last reply scheduled so far has been sent
        self._commands: deque[tuple[float, str, bytes]] = deque()  # (whole at, text, delimiter)
        self._replies: deque[tuple[float, bytes]] = deque()  # (due, bytes)

    def receive(self, data: bytes, t: float) -> None:
        """Bytes read at ``t``: each command in them is whole at its delimiter's arrival."""
        start = max(t, self._in_free)
        for text, index in self.splitter.feed(data):
            at = start + (index + 1) * self.byte_s
            self._commands.append((at, text, data[index : index + 1]))
        self._in_free = start + len(data) * self.byte_s

    def step(self, t: float) -> list[bytes]:
        """Answer the commands whole by ``t`` (each at its own time: on the unit's clock,
        that clock now less how long ago the command was whole); the replies due."""
        while self._commands and self._commands[0][0] <= t:
            at, text, delimiter = self._commands.popleft()
            unit_t = self.ptu.clock() - (t - at) if self.byte_s else None
            reply = self.ptu.handle(text, delimiter, unit_t)
            done = max(at, self._out_free) + len(reply) * self.byte_s
            self._out_free = done
            self._replies.append((done, reply))
        out = []
        while self._replies and self._replies[0][0] <= t:
            out.append(self._replies.popleft()[1])
        return out

    @property
    def next_due(self) -> float:
        """The next time ``step`` has something to do (inf if nothing)."""
        times = [q[0][0] for q in (self._commands, self._replies) if q]
        return min(times, default=float("inf"))


class PtyPtuLink(PtyLink):
    """Serves ``ptu`` on a new pseudo-terminal (``PtyLink``) at ``baud`` (the unit's
    power-up 9600 by default; None: unpaced, at any speed): paced at that rate, and
    deaf to a host whose line is set to another."""

    def __init__(
        self,
        ptu: EmulatedPtu,
        link: Path | str | None = None,
        *,
        baud: int | None = DEFAULT_BAUD,
        lifetime: float | None = None,
        poll: float = 0.02,
    ) -> None:
        self.ptu = ptu
        self.baud = baud
        self.timing = LineTiming(ptu, baud)
        super().__init__(link, baud=baud, lifetime=lifetime, poll=poll, name="ptu-emulator")

    def _hears(self) -> bool:
        """Whether the host's line is at the unit's rate (or either is unknown)."""
        speed = self.host_baud
        return self.baud is None or speed is None or speed == self.baud

    def _serve(self) -> None:
        timing = self.timing
        while self.running:
            wait = min(self._poll, max(0.0, timing.next_due - time.monotonic()))
            try:
                ready, _, _ = select.select([self._master], [], [], wait)
            except (OSError, ValueError):
                return
            if ready:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = None
                except OSError:
                    return  # the terminal is gone
                if data == b"":
                    return
                if data and self._hears():
                    timing.receive(data, time.monotonic())
            for reply in timing.step(time.monotonic()):
                self._send(reply)


class TcpPtuServer:
    """Serves ``ptu`` over TCP on ``host``:``port`` (0: a free port; ``address`` says
    which), one connection at a time, unpaced.  A thread of its own; ``close`` ends
    it.  DeviceError if the port cannot be bound."""

    def __init__(
        self, ptu: EmulatedPtu, host: str = "127.0.0.1", port: int = 0, *, poll: float = 0.02
    ) -> None:
        self.ptu = ptu
        self._poll = poll
        try:
            self._listener = socket.create_server((host, port))
        except OSError as exc:
            raise DeviceError(f"cannot listen on {host}:{port} for the PTU: {exc}") from exc
        self._listener.setblocking(False)
        self.connections = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="ptu-tcp-emulator", daemon=True)
        self._thread.start()

    @property
    def address(self) -> tuple[str, int]:
        host, port = self._listener.getsockname()[:2]
        return str(host), int(port)

    @property
    def uri(self) -> str:
        host, port = self.address
        return f"ptu://{host}:{port}"

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self._listener], [], [], self._poll)
                if not ready:
                    continue
                conn, _ = self._listener.accept()
            except BlockingIOError:
                continue
            except (OSError, ValueError):
                return
            self.connections += 1
            with conn:
                self._session(conn)

    def _session(self, conn: socket.socket) -> None:
        timing = LineTiming(self.ptu, None)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([conn], [], [], self._poll)
                if not ready:
                    continue
                data = conn.recv(4096)
            except OSError:
                return
            if not data:
                return  # the host closed
            timing.receive(data, time.monotonic())
            try:
                for reply in timing.step(time.monotonic()):
                    conn.sendall(reply)
            except OSError:
                return

    def close(self) -> None:
        """Stop serving and close the socket; safe to call twice."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        with contextlib.suppress(OSError):
            self._listener.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
