"""Ctrl-C: end a long loop between two of its steps, and keep what it has done.

The command line installs the handler (``handling_sigint``) for the length of a
command.  Inside a ``stoppable()`` block a first Ctrl-C (SIGINT) only sets a flag
that the loop reads between steps (``stop_requested``): the loop ends early, and
its caller writes what was done and reports the run as interrupted.  Nothing is
cut off in the middle of a step, so no numba kernel or half-written row sees the
interrupt.  A second Ctrl-C, or one outside a ``stoppable()`` block (loading,
compiling, writing plots), raises ``KeyboardInterrupt`` at once.

After the command, while the interpreter shuts down (threads joined, devices and DDS
participants closed), a Ctrl-C exits at once with the command's code
(``exit_on_sigint``): the work is done and written, and Python's default handling
would raise ``KeyboardInterrupt`` in the middle of the shutdown and die of the signal.
Before the command's own handling, and between its end and that, one exits with 130
(``cli.main``).  From the interpreter's exit handlers on a Ctrl-C is ignored: the
finalization after them puts a Python handler back to the default, and a Ctrl-C there,
while the C libraries' own exit handlers ran (DDS's), killed the process by the signal
(the slow tier stopping ``emulate --ros2`` as it ended by itself, under load: exit
status −2 in two runs of three).  So no moment is left in which a Ctrl-C kills a
command by the signal.

``handling_sigterm`` makes SIGTERM (a service manager's stop, ``kill``) do what
Ctrl-C does, for a command that must stop a device cleanly (``dronetrack live``).

Library code never installs the handlers: without them Ctrl-C raises
``KeyboardInterrupt`` as usual and ``stop_requested`` is always False.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from types import FrameType

__all__ = ["exit_on_sigint", "handling_sigint", "handling_sigterm", "stop_requested", "stoppable"]


@dataclass
class _State:
    installed: bool = False
    loops: int = 0  # stoppable() blocks open
    requested: bool = False
    ignore_at_exit: bool = False  # exit_on_sigint's exit handler registered


# Process-wide by nature: there is one SIGINT per process.
_state = _State()


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    if _state.loops > 0 and not _state.requested:
        _state.requested = True
        return
    raise KeyboardInterrupt


@contextmanager
def handling_sigint() -> Iterator[None]:
    """Handle Ctrl-C as this module says inside the block (main thread only; elsewhere
    the block runs with Python's default handling)."""
    if threading.current_thread() is not threading.main_thread() or _state.installed:
        yield
        return
    previous = signal.signal(signal.SIGINT, _on_sigint)
    _state.installed, _state.requested = True, False
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _state.installed, _state.requested, _state.loops = False, False, 0


@contextmanager
def handling_sigterm() -> Iterator[None]:
    """Inside the block SIGTERM acts as Ctrl-C does under ``handling_sigint``: inside a
    ``stoppable()`` loop the first one asks the loop to stop, otherwise it raises
    ``KeyboardInterrupt`` (main thread only; elsewhere the block runs unchanged)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if not _state.installed:  # without the SIGINT handling nobody else resets it
            _state.requested = False


@contextmanager
def stoppable() -> Iterator[None]:
    """A loop that reads ``stop_requested()`` between its steps."""
    _state.loops += 1
    try:
        yield
    finally:
        _state.loops -= 1


def stop_requested() -> bool:
    """Whether Ctrl-C asked the running loop to stop."""
    return _state.requested


def exit_on_sigint(code: int) -> None:
    """From now on a Ctrl-C flushes the standard streams and exits the process at once
    with ``code``, and once the interpreter's exit handlers run it is ignored (see the
    module docstring; main thread only, elsewhere nothing)."""
    if threading.current_thread() is not threading.main_thread():
        return

    def now(signum: int, frame: FrameType | None) -> None:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):  # closed, or its reader gone
                stream.flush()
        os._exit(code)

    signal.signal(signal.SIGINT, now)
    if not _state.ignore_at_exit:
        _state.ignore_at_exit = True
        atexit.register(_ignore_sigint)


def _ignore_sigint() -> None:
    """SIGINT ignored from here to the process's end.  The interpreter's finalization,
    after the exit handlers, puts a signal with a Python handler back to the default,
    which kills the process (exit status −2) while the C libraries' exit handlers run
    (DDS's own, under load for a second); an ignored one it leaves ignored.  A
    shutdown that hangs there still ends by SIGTERM (``kill``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
