"""A pseudo-terminal that serves an emulated serial device (the servos, the pan-tilt
unit): its slave end is the serial device a driver opens (optionally reachable
through a symlink).

Line speed.  A pseudo-terminal moves bytes whatever speed is set on it, but the speed
a host sets (pyserial's ``baudrate``, the DYNAMIXEL SDK's ``setBaudRate``: a
``tcsetattr`` on the slave end) stays in the terminal's settings, where the emulator
reads it back (``line_speed``) and, as a device at another rate would hear only
noise, stays silent when it is not the device's.  A rate with no ``B…`` constant
(pyserial sets those as Linux's ``BOTHER`` with the number in ``termios2``) is read
with the ``TCGETS2`` ioctl; a speed that cannot be read is taken as right.  The
terminal starts at the device's rate, as a port a previous session left set.
"""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import re
import select
import struct
import sys
import termios
import threading
import time
import tty
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Self

from dronetrack.errors import DeviceError
from dronetrack.formats.dynamixel import PacketParser
from dronetrack.sim.emulate.servo_bus import ServoBus

__all__ = ["PtyLink", "PtyServoLink", "line_speed", "set_line_speed"]

# termios speed constant → rate [baud], for every ``B<rate>`` this platform defines
_RATES = {
    getattr(termios, name): int(name[1:]) for name in dir(termios) if re.fullmatch(r"B\d+", name)
}
_CONSTANTS = {rate: code for code, rate in _RATES.items()}
# Linux: ``struct termios2`` (4 flag words, c_line, c_cc[19], c_ispeed, c_ospeed) and
# the ioctl that reads it (the asm-generic number: x86, ARM, RISC-V)
_TCGETS2 = 0x802C542A
_TERMIOS2 = struct.Struct("=4IB19sII")


def line_speed(fd: int) -> int | None:
    """The output speed [baud] set on terminal ``fd``; None if it cannot be read."""
    try:
        code = termios.tcgetattr(fd)[5]
    except (termios.error, OSError):
        return None
    rate = _RATES.get(code)
    if rate is not None or not sys.platform.startswith("linux"):
        return rate
    buffer = bytearray(_TERMIOS2.size)
    try:
        fcntl.ioctl(fd, _TCGETS2, buffer, True)
    except OSError:
        return None
    return int(_TERMIOS2.unpack(buffer)[-1])


def set_line_speed(fd: int, baud: int) -> bool:
    """Set terminal ``fd``'s input and output speed to ``baud``; False if the platform
    has no constant for that rate (nothing is changed then)."""
    code = _CONSTANTS.get(baud)
    if code is None:
        return False
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = code
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return True


def _points_to(link: Path, target: str) -> bool:
    """Whether ``link`` is a symlink to ``target``."""
    try:
        return os.readlink(link) == target
    except OSError:
        return False


def _link(link: Path, target: str) -> None:
    """Make ``link`` a symlink to ``target``, replacing a stale symlink (to a path that
    is gone: the pseudo-terminal of an emulator that has ended); DeviceError if it
    cannot be made (a file is there), or if ``link`` links to a device still there,
    most likely another running emulator's pseudo-terminal."""
    try:
        if link.is_symlink():
            if link.exists():
                raise DeviceError(
                    f"cannot link {link} to {target}: it links to {os.readlink(link)}, still "
                    "open, most likely another dronetrack emulate's (give another path, or "
                    "end that one)"
                )
            link.unlink()
        link.symlink_to(target)
    except OSError as exc:
        raise DeviceError(f"cannot link {link} to {target}: {exc}") from exc


class PtyLink(ABC):
    """A new pseudo-terminal served by a thread of its own (``_serve``, which subclasses
    write); ``device`` is what a driver opens.

    The slave end is put in raw mode (no echo, no line editing, no CR/LF or 8th-bit
    translation) so bytes pass untouched.  With ``link`` the slave path is also
    reachable through that symlink (replacing a stale symlink, never a file nor a
    symlink to a device still there, another emulator's); ``close`` removes it if it
    still points here.  ``baud``: the device's rate, which the terminal starts at (see
    the module docstring).  The serving thread polls a stop event every ``poll``
    seconds and ends after ``lifetime`` seconds if given.  The subclass sets what
    ``_serve`` needs before calling this ``__init__``, which starts the thread.
    """

    def __init__(
        self,
        link: Path | str | None = None,
        *,
        baud: int | None = None,
        lifetime: float | None = None,
        poll: float = 0.02,
        name: str = "pty-emulator",
    ) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        if baud is not None:
            set_line_speed(self._slave, baud)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self.link = Path(link) if link is not None else None
        if self.link is not None:
            try:
                _link(self.link, self.path)
            except DeviceError:
                self._close_fds()
                raise
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
    def host_baud(self) -> int | None:
        """The speed the host set on the line [baud]; None if it cannot be read."""
        return line_speed(self._slave)

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
        if self.link is not None and _points_to(self.link, self.path):
            with contextlib.suppress(OSError):
                self.link.unlink()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PtyServoLink(PtyLink):
    """Serves ``bus`` on a new pseudo-terminal (``PtyLink``); a partial packet is dropped
    after ``idle_reset`` seconds of silence, as a servo drops it after its own timeout.
    Each packet goes to the bus with the host's line speed, so a servo set to another
    rate does not hear it; the terminal starts at the servos' rate if they share one.
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
        rates = bus.rates()
        baud = rates.pop() if len(rates) == 1 else None
        super().__init__(link, baud=baud, lifetime=lifetime, poll=poll, name="dxl-emulator")

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
            speed = self.host_baud
            for packet in parser.feed(data):
                for reply in self.bus.handle(packet, speed):
                    self._send(reply)
