"""``dronetrack info dynamixel://DEVICE``: what the servos on a bus say of themselves,
read without changing anything on them."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Any

from dronetrack.actuators.dynamixel.port import IO_ERRORS, load_sdk, signed32
from dronetrack.actuators.dynamixel.uri import parse_dynamixel_uri
from dronetrack.errors import DeviceError
from dronetrack.formats.dynamixel import ADDR, ERROR_NAMES, ticks_to_rad

__all__ = ["ServoReport", "probe_servos"]


@dataclass(frozen=True, slots=True)
class ServoReport:
    """What one servo says of itself (``dronetrack info dynamixel://…``): its ID and
    role (pan, tilt, or other: answered a broadcast ping but is not in the URI),
    model number and firmware version from the ping, and for the turret's servos
    the present position [ticks and rad], torque enable and hardware error status;
    ``problem`` when a read failed."""

    ident: int
    role: str
    model: int | None
    firmware: int | None
    position: int | None = None
    torque: bool | None = None
    hardware_error: int | None = None
    problem: str | None = None

    @property
    def angle(self) -> float | None:
        return None if self.position is None else ticks_to_rad(self.position)


def probe_servos(uri: str) -> list[ServoReport]:
    """Ping every servo on the bus (a broadcast ping, then the URI's pan and tilt IDs one
    by one) and read the turret's: model, firmware, present position, torque and
    hardware error.  Changes nothing on the servos.  DeviceError if the port cannot
    be opened; a servo that does not answer is reported with its problem."""
    where = parse_dynamixel_uri(uri)
    sdk = load_sdk()
    port, ph = sdk.PortHandler(where.device), sdk.PacketHandler(2.0)
    try:
        opened = bool(port.openPort()) and bool(port.setBaudRate(where.baud))
    except IO_ERRORS as exc:
        raise DeviceError(f"Dynamixel bus on {where.device}: cannot open the port: {exc}") from exc
    if not opened:
        raise DeviceError(
            f"Dynamixel bus on {where.device}: cannot open the port at {where.baud} baud"
        )
    try:
        found: dict[int, tuple[int, int]] = {}
        try:
            answered, result = ph.broadcastPing(port)
            if result == sdk.COMM_SUCCESS:
                found = {int(i): (int(v[0]), int(v[1])) for i, v in answered.items()}
        except IO_ERRORS:
            found = {}
        roles = {where.pan_id: "pan", where.tilt_id: "tilt"}
        reports = [_servo_report(sdk, port, ph, i, r, found.get(i)) for i, r in roles.items()]
        reports += [
            ServoReport(i, "other", model, fw)
            for i, (model, fw) in sorted(found.items())
            if i not in roles
        ]
        return reports
    finally:
        with contextlib.suppress(*IO_ERRORS):
            port.closePort()


def _servo_report(
    sdk: Any, port: Any, ph: Any, ident: int, role: str, pinged: tuple[int, int] | None
) -> ServoReport:
    """One of the turret's servos: ping (unless the broadcast ping found it), then reads."""

    def failed(what: str, result: int, error: int) -> str | None:
        if result != sdk.COMM_SUCCESS:
            return f"{what}: {ph.getTxRxResult(result)}"
        if int(error) & 0x7F:
            return f"{what}: the servo answered {ERROR_NAMES.get(int(error) & 0x7F, error)}"
        return None

    try:
        if pinged is None:
            model, result, error = ph.ping(port, ident)
            problem = failed("ping", result, error)
            if problem is not None:
                return ServoReport(ident, role, None, None, problem=problem)
            fw, result, error = ph.read1ByteTxRx(port, ident, ADDR.FIRMWARE_VERSION)
            pinged = (int(model), int(fw) if failed("", result, error) is None else -1)
        model, fw = pinged
        position, result, error = ph.read4ByteTxRx(port, ident, ADDR.PRESENT_POSITION)
        problem = failed("read present position", result, error)
        torque, r2, e2 = ph.read1ByteTxRx(port, ident, ADDR.TORQUE_ENABLE)
        hw, r3, e3 = ph.read1ByteTxRx(port, ident, ADDR.HARDWARE_ERROR)
        problem = problem or failed("read torque enable", r2, e2) or failed("read error", r3, e3)
    except IO_ERRORS as exc:
        return ServoReport(ident, role, None, None, problem=str(exc))
    return ServoReport(
        ident,
        role,
        model,
        None if fw < 0 else fw,
        signed32(int(position)) if problem is None else None,
        bool(torque) if problem is None else None,
        int(hw) if problem is None else None,
        problem,
    )
