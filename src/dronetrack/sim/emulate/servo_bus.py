"""Emulated XM430s sharing one bus: each received Protocol 2.0 packet turned into the
status packets the protocol prescribes (none for broadcast reads and writes and for
sync write; one per listed servo, in the listed order, for sync read; one per servo
in ID order for a broadcast ping).  A packet sent at another rate than a servo's own
(its Baud Rate item) is noise to that servo: it neither acts on it nor answers."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable

from dronetrack.errors import DeviceError
from dronetrack.formats.dynamixel import (
    ADDR,
    BAUD_RATE_CODES,
    BROADCAST_ID,
    BadPacket,
    Err,
    Inst,
    Packet,
    encode_status,
)
from dronetrack.sim.emulate.xm430 import FIRMWARE_VERSION, Clock, EmulatedXM430, JointModel

__all__ = ["ServoBus", "turret_bus"]


class ServoBus:
    """Servos sharing one bus; ``handle`` gives the status packets a packet calls for.

    Every method takes ``lock``, so tests may inspect servos while a link serves.
    """

    def __init__(self, servos: Iterable[EmulatedXM430], clock: Clock = time.monotonic) -> None:
        self.servos = list(servos)
        idents = [s.ident for s in self.servos]
        if len(set(idents)) != len(idents):
            raise DeviceError(f"emulated servos need distinct IDs, got {idents}")
        self.clock = clock
        self.lock = threading.RLock()

    def servo(self, ident: int) -> EmulatedXM430:
        with self.lock:
            for s in self.servos:
                if s.ident == ident:
                    return s
        raise DeviceError(f"no emulated servo with ID {ident}")

    def rates(self) -> set[int]:
        """The rates [baud] the servos listen at (their Baud Rate items)."""
        with self.lock:
            return {s.baud for s in self.servos}

    def _present(self, ident: int, hearing: list[EmulatedXM430]) -> EmulatedXM430 | None:
        for s in hearing:
            if s.ident == ident:
                return s
        return None

    def value(self, ident: int, address: int) -> int:
        """A control-table value of servo ``ident`` now (live items refreshed)."""
        with self.lock:
            s = self.servo(ident)
            s.refresh(self.clock())
            return s.values[address]

    def set_online(self, ident: int, online: bool) -> None:
        with self.lock:
            self.servo(ident).online = online

    def handle(self, packet: Packet | BadPacket, baud: int | None = None) -> list[bytes]:
        """The status packets ``packet``, sent at ``baud`` (None: whatever rate the
        servos are at), calls for from the servos online at that rate."""
        with self.lock:
            hearing = [s for s in self.servos if s.online and baud in (None, s.baud)]
            return self._handle(packet, self.clock(), hearing)

    def _handle(
        self, packet: Packet | BadPacket, t: float, hearing: list[EmulatedXM430]
    ) -> list[bytes]:
        if isinstance(packet, BadPacket):
            s = self._present(packet.ident, hearing) if packet.crc else None
            return [encode_status(s.ident, s.error_byte(Err.CRC))] if s is not None else []
        if packet.is_status:
            return []  # another device's answer
        inst, p = packet.instruction, packet.params
        if packet.ident == BROADCAST_ID:
            return self._broadcast(inst, p, t, hearing)
        s = self._present(packet.ident, hearing)
        if s is None:
            return []
        level = s.values[ADDR.STATUS_RETURN_LEVEL]
        if inst == Inst.PING:
            return [self._ping(s)]
        if inst == Inst.READ:
            if len(p) != 4:
                return [encode_status(s.ident, s.error_byte(Err.INSTRUCTION))] if level else []
            err, data = s.read(int.from_bytes(p[:2], "little"), int.from_bytes(p[2:], "little"), t)
            return [encode_status(s.ident, s.error_byte(err), data)] if level >= 1 else []
        if inst == Inst.WRITE:
            err = (
                s.write(int.from_bytes(p[:2], "little"), p[2:], t)
                if len(p) >= 3
                else Err.INSTRUCTION
            )
            return [encode_status(s.ident, s.error_byte(err))] if level >= 2 else []
        if inst == Inst.REBOOT:
            reply = encode_status(s.ident, s.error_byte(Err.NONE))
            s.reboot(t)
            return [reply] if level >= 2 else []
        return [encode_status(s.ident, s.error_byte(Err.INSTRUCTION))] if level >= 2 else []

    def _ping(self, s: EmulatedXM430) -> bytes:
        model = s.values[ADDR.MODEL_NUMBER].to_bytes(2, "little")
        return encode_status(s.ident, s.error_byte(Err.NONE), model + bytes([FIRMWARE_VERSION]))

    def _broadcast(
        self, inst: int, p: bytes, t: float, hearing: list[EmulatedXM430]
    ) -> list[bytes]:
        online = sorted(hearing, key=lambda s: s.ident)
        if inst == Inst.PING:
            return [self._ping(s) for s in online]
        if inst == Inst.WRITE and len(p) >= 3:
            for s in online:
                s.write(int.from_bytes(p[:2], "little"), p[2:], t)
        elif inst == Inst.SYNC_WRITE and len(p) >= 5:
            address, length = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            blocks = p[4:]
            if length >= 1 and len(blocks) % (length + 1) == 0:
                for k in range(0, len(blocks), length + 1):
                    target = self._present(blocks[k], hearing)
                    if target is not None:
                        target.write(address, blocks[k + 1 : k + 1 + length], t)
        elif inst == Inst.SYNC_READ and len(p) >= 5:
            address, length = int.from_bytes(p[:2], "little"), int.from_bytes(p[2:4], "little")
            replies = []
            for ident in p[4:]:  # each listed servo answers in the listed order
                listed = self._present(ident, hearing)
                if listed is not None and listed.values[ADDR.STATUS_RETURN_LEVEL] >= 1:
                    err, data = listed.read(address, length, t)
                    replies.append(encode_status(ident, listed.error_byte(err), data))
            return replies
        elif inst == Inst.REBOOT:
            for s in online:
                s.reboot(t)
        return []


def turret_bus(
    pan_id: int = 1,
    tilt_id: int = 2,
    clock: Clock = time.monotonic,
    pan: JointModel | None = None,
    tilt: JointModel | None = None,
    baud: int = 1_000_000,
) -> ServoBus:
    """A pan-tilt turret's two servos, factory-set but for their IDs and their rate
    (``baud``, one of ``BAUD_RATE_CODES``: 1 Mbit/s, as Interbotix sets a WidowX's
    and as ``dynamixel://`` assumes; the factory's is 57,600)."""
    if baud not in BAUD_RATE_CODES:
        raise DeviceError(f"an XM430 runs at one of {BAUD_RATE_CODES} baud, not {baud}")
    servos = [EmulatedXM430(pan_id, pan), EmulatedXM430(tilt_id, tilt)]
    for s in servos:
        s.values[ADDR.BAUD_RATE] = BAUD_RATE_CODES.index(baud)
    return ServoBus(servos, clock)
