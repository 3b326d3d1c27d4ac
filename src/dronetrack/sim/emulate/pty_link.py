"""A pseudo-terminal that serves an emulated serial device (the servos, the pan-tilt
unit): its slave end is the serial device a driver opens (optionally reachable
through a symlink)."""

from __future__ import annotations

import contextlib
import math
import os
import select
import threading
import time
import tty
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Self

from dronetrack.errors import DeviceError
from dronetrack.formats.dynamixel import PacketParser
from dronetrack.sim.emulate.servo_bus import ServoBus

__all__ = ["PtyLink", "PtyServoLink"]


class PtyLink(ABC):
    """A new pseudo-terminal served by a thread of its own (``_serve``, which subclasses
    write); ``device`` is what a driver opens.

    The slave end is put in raw mode (no echo, no line editing, no CR/LF or 8th-bit
    translation) so bytes pass untouched.  With ``link`` the slave path is also
    reachable through that symlink (replacing a stale symlink, never a file).  The
    serving thread polls a stop event every ``poll`` seconds and ends after
    ``lifetime`` seconds if given.  The subclass sets what ``_serve`` needs before
    calling this ``__init__``, which starts the thread.
    """

    def __init__(
        self,
        link: Path | str | None = None,
        *,
        lifetime: float | None = None,
        poll: float = 0.02,
        name: str = "pty-emulator",
    ) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.link = Path(link) if link is not None else None
        if self.link is not None:
            try:
                if self.link.is_symlink():
                    self.link.unlink()
                self.link.symlink_to(self.path)
            except OSError as exc:
                self._close_fds()
                raise DeviceError(f"cannot link {self.link} to {self.path}: {exc}") from exc
        self._poll = poll
        self._deadline = time.monotonic() + lifetime if lifetime is not None else math.inf
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    @property
    def device(self) -> str:
        """The path a driver opens: the link if one was asked for, else the pty slave."""
        return str(self.link) if self.link is not None else self.path

    @property
    def serving(self) -> bool:
        return self._thread.is_alive()

    @property
    def running(self) -> bool:
        """Neither closed nor past its lifetime."""
        return not self._stop.is_set() and time.monotonic() < self._deadline

    @abstractmethod
    def _serve(self) -> None:
        """The serving thread's loop (until ``running`` is false or the terminal goes)."""

    def _send(self, data: bytes) -> None:
        """Write ``data`` to the master end, waiting at most 0.1 s for room; else drop it."""
        view, deadline = memoryview(data), time.monotonic() + 0.1
        while view and time.monotonic() < deadline and not self._stop.is_set():
            try:
                view = view[os.write(self._master, view) :]
            except BlockingIOError:
                select.select([], [self._master], [], 0.01)
            except OSError:
                return

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def close(self) -> None:
        """Stop serving, close the terminal and remove the link; safe to call twice."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._close_fds()
        if self.link is not None and self.link.is_symlink():
            self.link.unlink()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PtyServoLink(PtyLink):
    """Serves ``bus`` on a new pseudo-terminal (``PtyLink``); a partial packet is dropped
    after ``idle_reset`` seconds of silence, as a servo drops it after its own timeout.
    """

    def __init__(
        self,
        bus: ServoBus,
        link: Path | str | None = None,
        *,
        lifetime: float | None = None,
        poll: float = 0.02,
        idle_reset: float = 0.05,
    ) -> None:
        self.bus = bus
        self._idle_reset = idle_reset
        super().__init__(link, lifetime=lifetime, poll=poll, name="dxl-emulator")

    def _serve(self) -> None:
        parser = PacketParser()
        last = time.monotonic()
        while self.running:
            try:
                ready, _, _ = select.select([self._master], [], [], self._poll)
            except (OSError, ValueError):
                return
            if not ready:
                if parser.pending and time.monotonic() - last > self._idle_reset:
                    parser.reset()
                continue
            try:
                data = os.read(self._master, 4096)
            except BlockingIOError:
                continue
            except OSError:
                return  # the terminal is gone
            if not data:
                return
            last = time.monotonic()
            for packet in parser.feed(data):
                for reply in self.bus.handle(packet):
                    self._send(reply)
