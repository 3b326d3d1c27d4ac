"""The serial line to a turret's DYNAMIXEL servos, through the official SDK.

``ServoPort`` opens the port with the SDK's ``PortHandler`` and ``PacketHandler``
(Protocol 2.0) and runs every request/response on it **one transaction at a time**:
a lock is held for the whole exchange, because the SDK's ``txPacket`` clears the
input buffer before it writes, so a second thread's write would throw away the
first's status packets.  A failed or timed-out exchange raises ``DeviceError``
naming the device and the servo ID(s).

Waiting for a status packet.  The SDK's receive loop asks the port for bytes over
and over (pyserial with ``timeout=0``) until the packet is whole or its time-out
passes: on a busy 2-core machine that spinning thread takes a core from whoever is
to answer, and the interpreter from the other threads.  ``ServoPort``'s port
handler waits instead: when no byte is there, ``readPort`` blocks in ``select`` on
the serial descriptor for at most ``READ_WAIT_S`` (the interpreter is released
meanwhile) before it reads.  A byte that arrives ends the wait at once, and the
SDK's own time-out, checked after every ``readPort``, is untouched.
"""

from __future__ import annotations

import contextlib
import select
import threading
from collections.abc import Callable
from functools import partial
from typing import Any

from dronetrack.errors import DeviceError, MissingExtraError
from dronetrack.formats.dynamixel import ERROR_NAMES, Err

__all__ = [
    "IO_ERRORS",
    "READ_WAIT_S",
    "ServoPort",
    "le32",
    "load_sdk",
    "no_servo_answered",
    "signed32",
]

READ_WAIT_S = 0.001  # longest a read waits for the first byte before the SDK looks again


def _io_errors() -> tuple[type[BaseException], ...]:
    """What the SDK's serial layer raises when the line fails: OSError (pyserial's
    SerialException is one) and, on POSIX, termios.error (not an OSError)."""
    try:
        import termios
    except ImportError:
        return (OSError,)
    return (OSError, termios.error)


IO_ERRORS = _io_errors()


def load_sdk() -> Any:
    """The ``dynamixel_sdk`` module; MissingExtraError naming the extra if it is absent."""
    try:
        import dynamixel_sdk
    except ImportError as exc:
        raise MissingExtraError(
            "the Dynamixel turret needs the official DYNAMIXEL SDK: "
            "pip install 'dronetrack[live]' (dynamixel-sdk, pyserial)"
        ) from exc
    return dynamixel_sdk


def signed32(value: int) -> int:
    """A 4-byte control-table value as the signed integer it encodes (two's complement)."""
    value &= 0xFFFFFFFF
    return value - (1 << 32) if value & 0x80000000 else value


def no_servo_answered(device: str, baud: int) -> str:
    """The one line saying that nothing on the bus answered at ``baud``."""
    return (
        f"Dynamixel turret on {device}: no servo answered at {baud} baud, not even a "
        "broadcast ping: check the URI's baud= (the servos' Baud Rate), the power and "
        "the wiring"
    )


def le32(value: int) -> list[int]:
    """A 4-byte control-table value as its little-endian bytes."""
    return list((value & 0xFFFFFFFF).to_bytes(4, "little"))


def _waiting_port_handler(sdk: Any, device: str) -> Any:
    """The SDK's PortHandler for ``device``, with a ``readPort`` that waits for the first
    byte in ``select`` (see the module docstring) instead of returning nothing."""

    class WaitingPortHandler(sdk.PortHandler):  # type: ignore[misc]
        def readPort(self, length: int) -> Any:  # noqa: N802 (the SDK's name)
            ser = self.ser
            if ser is not None and not ser.in_waiting:
                with contextlib.suppress(ValueError):  # a closed descriptor: read says so
                    select.select([ser.fileno()], [], [], READ_WAIT_S)
            return super().readPort(length)

    return WaitingPortHandler(device)


class ServoPort:
    """An open serial port to servos ``ids`` = (pan, tilt) on ``device`` at ``baud``.

    ``lock`` is held for each exchange (``exchange``, ``read``, ``write``,
    ``group``); callers that make several exchanges one unit hold it around them
    (it is re-entrant).  DeviceError if the port cannot be opened.
    """

    def __init__(self, device: str, baud: int, ids: tuple[int, int]) -> None:
        sdk = load_sdk()
        self.sdk = sdk
        self.device = device
        self.baud = baud
        self.ids = ids
        self.ok = sdk.COMM_SUCCESS
        self.lock = threading.RLock()
        self.port = _waiting_port_handler(sdk, device)
        self.ph = sdk.PacketHandler(2.0)
        self.closed = True
        try:
            opened = bool(self.port.openPort()) and bool(self.port.setBaudRate(baud))
        except IO_ERRORS as exc:
            raise DeviceError(f"Dynamixel turret on {device}: cannot open the port: {exc}") from exc
        if not opened:
            raise DeviceError(f"Dynamixel turret on {device}: cannot open the port at {baud} baud")
        self.closed = False

    # -- names -------------------------------------------------------------------------

    def who(self, ident: int) -> str:
        axis = "pan" if ident == self.ids[0] else "tilt"
        return f"Dynamixel turret on {self.device}: servo ID {ident} ({axis})"

    @property
    def both(self) -> str:
        return f"Dynamixel turret on {self.device}: servo IDs {self.ids[0]}, {self.ids[1]}"

    # -- exchanges -----------------------------------------------------------------------

    def exchange(self, ident: int, what: str, call: Callable[[], tuple[Any, ...]]) -> Any:
        """Run one SDK request/response; its value, or DeviceError naming the servo."""
        with self.lock:
            if self.closed:
                raise DeviceError(f"{self.who(ident)}: {what}: the port is closed")
            try:
                *value, result, error = call()
            except IO_ERRORS as exc:
                raise DeviceError(f"{self.who(ident)}: {what}: {exc}") from exc
        if result != self.ok:
            raise DeviceError(f"{self.who(ident)}: {what}: {self.ph.getTxRxResult(result)}")
        number = int(error) & 0x7F
        if number:
            name = ERROR_NAMES.get(number, f"error {number}")
            raise DeviceError(f"{self.who(ident)}: {what}: the servo answered {name}")
        if int(error) & Err.ALERT:
            raise DeviceError(
                f"{self.who(ident)}: {what}: hardware alert (read Hardware Error Status, 70)"
            )
        return value[0] if value else None

    def read(self, ident: int, address: int, size: int, what: str) -> int:
        reader = {1: self.ph.read1ByteTxRx, 4: self.ph.read4ByteTxRx}[size]
        value = self.exchange(ident, f"read {what}", lambda: reader(self.port, ident, address))
        return signed32(int(value)) if size == 4 else int(value)

    def write(self, ident: int, address: int, size: int, value: int, what: str) -> None:
        writer = {1: self.ph.write1ByteTxRx, 4: self.ph.write4ByteTxRx}[size]
        data = value & 0xFFFFFFFF
        self.exchange(ident, f"write {what}", lambda: writer(self.port, ident, address, data))

    def ping(self, ident: int) -> int:
        """The model number servo ``ident`` answers a ping with."""
        return int(self.exchange(ident, "ping", partial(self.ph.ping, self.port, ident)))

    def group(self, what: str, call: Callable[[], int]) -> int:
        """Run one sync read or write of both servos; the SDK's result code, or
        DeviceError naming both servos when the port is closed or the line fails."""
        with self.lock:
            if self.closed:
                raise DeviceError(f"Dynamixel turret on {self.device}: the port is closed")
            try:
                return call()
            except IO_ERRORS as exc:
                raise DeviceError(f"{self.both}: {what}: {exc}") from exc

    def bus_silent(self) -> bool:
        """Whether no servo at all answers a broadcast ping (the line fails: silent too)."""
        with self.lock:
            try:
                found, result = self.ph.broadcastPing(self.port)
            except IO_ERRORS:
                return True
        return result != self.ok or not found

    def first_silent(self) -> int:
        """The first servo that does not answer a ping (-1 if both do): who to name when
        a sync read fails."""
        for ident in self.ids:
            try:
                self.ping(ident)
            except DeviceError:
                return ident
        return -1

    def result_text(self, result: int) -> str:
        return str(self.ph.getTxRxResult(result))

    # -- closing -------------------------------------------------------------------------

    def close(self) -> None:
        """Close the port (waiting for an exchange under way); safe to call twice."""
        with self.lock:
            self.closed = True
            if getattr(self.port, "ser", None) is not None:
                with contextlib.suppress(*IO_ERRORS):
                    self.port.closePort()
