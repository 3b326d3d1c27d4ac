"""The emulated XM430-W350s against the official DYNAMIXEL SDK (ROBOTIS' own
Protocol 2.0 client) on a pseudo-terminal: what the SDK sends, the emulator must
answer as the protocol document and the XM430 control table say."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from dronetrack.errors import DeviceError
from dronetrack.formats.dynamixel import (
    ADDR,
    BROADCAST_ID,
    Err,
    Inst,
    Packet,
    PacketParser,
    encode_instruction,
    read_params,
    sync_read_params,
    units_to_rate,
)
from dronetrack.sim.emulate.servos import (
    EmulatedXM430,
    PtyServoLink,
    RateLimitedJoint,
    ServoBus,
    turret_bus,
)

sdk = pytest.importorskip("dynamixel_sdk")


class ManualClock:
    """A clock the test moves by hand, so motion has exact known answers."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


@pytest.fixture
def bus(clock: ManualClock) -> ServoBus:
    return turret_bus(1, 2, clock)


@pytest.fixture
def link(bus: ServoBus) -> Iterator[PtyServoLink]:
    with PtyServoLink(bus, lifetime=60.0) as served:
        yield served


@pytest.fixture
def port(link: PtyServoLink) -> Iterator[Any]:
    handle = sdk.PortHandler(link.device)
    assert handle.openPort()
    assert handle.setBaudRate(1_000_000)
    yield handle
    handle.closePort()


@pytest.fixture
def ph() -> Any:
    return sdk.PacketHandler(2.0)


def _ok(answer: tuple[Any, ...]) -> Any:
    """The value of an SDK (value…, result, error) answer that must have succeeded."""
    *value, result, error = answer
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    return value[0] if value else None


def _raw_exchange(port: Any, packet: bytes, expect: int, wait: float = 0.5) -> list[Packet]:
    """Send raw bytes through the SDK's port; the packets that come back (at most
    ``expect``, waiting at most ``wait`` seconds)."""
    port.clearPort()
    assert port.writePort(packet) == len(packet)
    parser, found, deadline = PacketParser(), [], time.monotonic() + wait
    while len(found) < expect and time.monotonic() < deadline:
        chunk = port.readPort(256)
        if chunk:
            found += [p for p in parser.feed(chunk) if isinstance(p, Packet)]
        else:
            time.sleep(0.001)
    return found


def test_ping_answers_model_1020(port: Any, ph: Any) -> None:
    assert _ok(ph.ping(port, 1)) == 1020
    assert _ok(ph.ping(port, 2)) == 1020
    _, result, _ = ph.ping(port, 9)  # nobody has ID 9
    assert result == sdk.COMM_RX_TIMEOUT


def test_broadcast_ping_answers_in_id_order(bus: ServoBus, port: Any) -> None:
    bus.servos.reverse()  # the order on the bus is not the answer order
    replies = _raw_exchange(port, encode_instruction(BROADCAST_ID, Inst.PING), expect=3, wait=0.2)
    assert [(r.ident, r.error, r.data[:2]) for r in replies] == [
        (1, 0, (1020).to_bytes(2, "little")),
        (2, 0, (1020).to_bytes(2, "little")),
    ]


def test_read_and_write_goal_and_present_position(clock: ManualClock, port: Any, ph: Any) -> None:
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.PRESENT_POSITION)) == 2048
    _ok(ph.write1ByteTxRx(port, 1, ADDR.TORQUE_ENABLE, 1))
    # profile velocity 0: the goal is reached at once
    _ok(ph.write4ByteTxRx(port, 1, ADDR.GOAL_POSITION, 3072))
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.GOAL_POSITION)) == 3072
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.PRESENT_POSITION)) == 3072
    # 131 × 0.229 rpm: 131 · 0.229 / 60 · 4096 = 2047.9 ticks/s, so 512 ticks in 0.25 s
    _ok(ph.write4ByteTxRx(port, 1, ADDR.PROFILE_VELOCITY, 131))
    _ok(ph.write4ByteTxRx(port, 1, ADDR.GOAL_POSITION, 2048))
    clock.t = 0.25
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.PRESENT_POSITION)) == 3072 - 512
    velocity = _ok(ph.read4ByteTxRx(port, 1, ADDR.PRESENT_VELOCITY))
    assert velocity == (-131) & 0xFFFFFFFF  # signed: 131 units toward the goal
    assert _ok(ph.read1ByteTxRx(port, 1, ADDR.MOVING)) == 1
    clock.t = 0.6
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.PRESENT_POSITION)) == 2048
    assert _ok(ph.read1ByteTxRx(port, 1, ADDR.MOVING)) == 0
    # the other servo did not move
    assert _ok(ph.read4ByteTxRx(port, 2, ADDR.PRESENT_POSITION)) == 2048


def test_group_sync_write_and_group_sync_read(port: Any, ph: Any) -> None:
    for ident in (1, 2):
        _ok(ph.write1ByteTxRx(port, ident, ADDR.TORQUE_ENABLE, 1))
    write = sdk.GroupSyncWrite(port, ph, ADDR.GOAL_POSITION, 4)
    for ident, goal in ((1, 1000), (2, 3000)):
        assert write.addParam(ident, list(goal.to_bytes(4, "little")))
    assert write.txPacket() == sdk.COMM_SUCCESS
    read = sdk.GroupSyncRead(port, ph, ADDR.PRESENT_POSITION, 4)
    assert read.addParam(1)
    assert read.addParam(2)
    assert read.txRxPacket() == sdk.COMM_SUCCESS
    assert read.getData(1, ADDR.PRESENT_POSITION, 4) == 1000
    assert read.getData(2, ADDR.PRESENT_POSITION, 4) == 3000


def test_sync_read_answers_in_the_listed_order(port: Any) -> None:
    request = encode_instruction(BROADCAST_ID, Inst.SYNC_READ, sync_read_params(7, 1, [2, 9, 1]))
    replies = _raw_exchange(port, request, expect=3, wait=0.2)
    # ID 9 is absent and stays silent; each status carries the servo's ID (address 7)
    assert [(r.ident, r.error, r.data) for r in replies] == [(2, 0, b"\x02"), (1, 0, b"\x01")]


def test_an_unknown_instruction_gives_an_instruction_error(port: Any, ph: Any) -> None:
    replies = _raw_exchange(port, encode_instruction(1, 0x7F), expect=1)
    assert [(r.ident, r.error_number, r.alert) for r in replies] == [(1, Err.INSTRUCTION, False)]
    assert "Undefined instruction" in ph.getRxPacketError(replies[0].error)


def test_a_bad_crc_gives_a_crc_error_read_by_the_sdk(port: Any, ph: Any) -> None:
    bad = bytearray(encode_instruction(2, Inst.READ, read_params(ADDR.PRESENT_POSITION, 4)))
    bad[-2] ^= 0xFF
    port.clearPort()
    port.writePort(bytes(bad))
    port.setPacketTimeout(11)
    status, result = ph.rxPacket(port, False)  # the SDK's own status-packet reader
    assert result == sdk.COMM_SUCCESS
    assert (status[4], status[7], status[8]) == (2, Inst.STATUS, Err.CRC)
    assert "CRC" in ph.getRxPacketError(status[8])


def test_eeprom_write_with_torque_on_is_an_access_error(port: Any, ph: Any) -> None:
    _ok(ph.write1ByteTxRx(port, 1, ADDR.TORQUE_ENABLE, 1))
    result, error = ph.write1ByteTxRx(port, 1, ADDR.OPERATING_MODE, 3)
    assert (result, error) == (sdk.COMM_SUCCESS, Err.ACCESS)
    assert "not available" in ph.getRxPacketError(error)
    result, error = ph.write4ByteTxRx(port, 1, ADDR.MAX_POSITION, 3000)
    assert error == Err.ACCESS
    _ok(ph.write1ByteTxRx(port, 1, ADDR.TORQUE_ENABLE, 0))
    _ok(ph.write4ByteTxRx(port, 1, ADDR.MAX_POSITION, 3000))  # unlocked with torque off


@pytest.mark.parametrize(
    ("address", "size", "value", "error"),
    [
        (ADDR.TORQUE_ENABLE, 1, 2, Err.DATA_RANGE),  # 0–1
        (ADDR.OPERATING_MODE, 1, 2, Err.DATA_RANGE),  # 2 is not a mode
        (ADDR.GOAL_POSITION, 4, 3500, Err.DATA_LIMIT),  # above the max position limit 3000
        (ADDR.PROFILE_VELOCITY, 4, 400, Err.DATA_LIMIT),  # above the velocity limit 350
        (ADDR.PRESENT_POSITION, 4, 0, Err.ACCESS),  # read-only
        (ADDR.MODEL_NUMBER, 2, 1, Err.ACCESS),  # read-only
        (ADDR.GOAL_POSITION + 1, 1, 0, Err.DATA_LENGTH),  # inside an item
    ],
)
def test_write_errors(port: Any, ph: Any, address: int, size: int, value: int, error: int) -> None:
    _ok(ph.write4ByteTxRx(port, 1, ADDR.MAX_POSITION, 3000))
    before = _ok(ph.read4ByteTxRx(port, 1, ADDR.GOAL_POSITION))
    writer = {1: ph.write1ByteTxRx, 2: ph.write2ByteTxRx, 4: ph.write4ByteTxRx}[size]
    assert writer(port, 1, address, value) == (sdk.COMM_SUCCESS, error)
    assert _ok(ph.read4ByteTxRx(port, 1, ADDR.GOAL_POSITION)) == before  # nothing changed


def test_reads_of_undefined_addresses_are_access_errors(port: Any, ph: Any) -> None:
    _, result, error = ph.read1ByteTxRx(port, 1, 200)
    assert (result, error) == (sdk.COMM_SUCCESS, Err.ACCESS)
    _, result, error = ph.readTxRx(port, 1, ADDR.PRESENT_POSITION, 40)  # runs past the end
    assert (result, error) == (sdk.COMM_SUCCESS, Err.ACCESS)


def test_broadcast_write_is_applied_without_an_answer(port: Any, ph: Any) -> None:
    write = encode_instruction(BROADCAST_ID, Inst.WRITE, bytes([ADDR.LED, 0, 1]))
    assert _raw_exchange(port, write, expect=1, wait=0.05) == []
    assert _ok(ph.read1ByteTxRx(port, 1, ADDR.LED)) == 1
    assert _ok(ph.read1ByteTxRx(port, 2, ADDR.LED)) == 1


def test_reboot_answers_and_turns_torque_off(port: Any, ph: Any) -> None:
    _ok(ph.write1ByteTxRx(port, 2, ADDR.TORQUE_ENABLE, 1))
    _ok(ph.reboot(port, 2))
    assert _ok(ph.read1ByteTxRx(port, 2, ADDR.TORQUE_ENABLE)) == 0


def test_status_return_level_zero_answers_ping_only(port: Any, ph: Any) -> None:
    _ok(ph.write1ByteTxRx(port, 1, ADDR.STATUS_RETURN_LEVEL, 0))
    assert _ok(ph.ping(port, 1)) == 1020
    _, result, _ = ph.read1ByteTxRx(port, 1, ADDR.ID)
    assert result == sdk.COMM_RX_TIMEOUT


def test_hardware_error_sets_the_alert_bit(bus: ServoBus, port: Any, ph: Any) -> None:
    with bus.lock:
        bus.servo(1).values[ADDR.HARDWARE_ERROR] = 0x20  # overload
    _, result, error = ph.read1ByteTxRx(port, 1, ADDR.ID)
    assert (result, error) == (sdk.COMM_SUCCESS, Err.ALERT)
    assert "Hardware error" in ph.getRxPacketError(error)


def test_an_unplugged_servo_does_not_answer(bus: ServoBus, port: Any, ph: Any) -> None:
    bus.set_online(2, False)
    _, result, _ = ph.ping(port, 2)
    assert result == sdk.COMM_RX_TIMEOUT
    assert _ok(ph.ping(port, 1)) == 1020


def test_a_host_at_another_baud_rate_gets_no_answer(port: Any, ph: Any) -> None:
    # the turret's servos run at 1 Mbit/s: at 57,600 baud nothing hears the host
    assert port.setBaudRate(57_600)
    _, result, _ = ph.ping(port, 1)
    assert result == sdk.COMM_RX_TIMEOUT
    found, result = ph.broadcastPing(port)
    assert found == {}
    # nor is a write acted on
    result, _ = ph.write1ByteTxRx(port, 1, ADDR.LED, 1)
    assert result == sdk.COMM_RX_TIMEOUT
    assert port.setBaudRate(1_000_000)
    assert _ok(ph.read1ByteTxRx(port, 1, ADDR.LED)) == 0
    assert _ok(ph.ping(port, 1)) == 1020


def test_a_servo_hears_at_the_rate_its_baud_rate_item_sets(port: Any, ph: Any) -> None:
    _ok(ph.write1ByteTxRx(port, 2, ADDR.BAUD_RATE, 1))  # code 1: 57,600 baud
    _, result, _ = ph.ping(port, 2)
    assert result == sdk.COMM_RX_TIMEOUT
    assert _ok(ph.ping(port, 1)) == 1020
    assert port.setBaudRate(57_600)
    assert _ok(ph.ping(port, 2)) == 1020
    _, result, _ = ph.ping(port, 1)
    assert result == sdk.COMM_RX_TIMEOUT


@pytest.mark.parametrize("baud", [9600, 57_600, 1_000_000, 4_000_000])
def test_the_line_speed_the_sdk_sets_is_read_back(baud: int) -> None:
    with PtyServoLink(turret_bus(), lifetime=30.0) as served:
        assert served.host_baud == 1_000_000  # the terminal starts at the servos' rate
        handle = sdk.PortHandler(served.device)
        assert handle.openPort()
        try:
            assert handle.setBaudRate(baud)
            assert served.host_baud == baud
        finally:
            handle.closePort()


def test_a_rate_with_no_termios_constant_is_read_back() -> None:
    serial = pytest.importorskip("serial")
    # 4.5 Mbit/s (an XM430's code 7): pyserial sets it as a custom rate (Linux's BOTHER)
    with PtyServoLink(turret_bus(baud=4_500_000), lifetime=30.0) as served:
        with serial.Serial(served.device, baudrate=4_500_000, timeout=0.5) as line:
            assert served.host_baud == 4_500_000
            line.write(encode_instruction(1, Inst.PING))
            replies = PacketParser().feed(line.read(14))
        assert [(r.ident, r.data[:2]) for r in replies] == [(1, (1020).to_bytes(2, "little"))]


def _ping_through(path: Path, servo_id: int) -> int:
    """The model number servo ``servo_id`` answers a ping with, the SDK opening ``path``."""
    handle = sdk.PortHandler(str(path))
    assert handle.openPort()
    assert handle.setBaudRate(1_000_000)  # the turret's servos' rate
    try:
        return int(_ok(sdk.PacketHandler(2.0).ping(handle, servo_id)))
    finally:
        handle.closePort()


def test_the_link_path_reaches_the_emulator_and_goes_away(tmp_path: Path) -> None:
    path = tmp_path / "ttyDXL"
    served = PtyServoLink(turret_bus(), link=path, lifetime=30.0)
    try:
        assert path.is_symlink()
        assert os.path.realpath(path) == os.path.realpath(served.path)
        assert _ping_through(path, 2) == 1020
    finally:
        served.close()
    assert not path.exists()
    assert not path.is_symlink()
    assert not served.serving


def test_a_link_to_a_running_emulator_is_refused_and_still_reaches_it(tmp_path: Path) -> None:
    path = tmp_path / "ttyDXL"
    first = PtyServoLink(turret_bus(), link=path, lifetime=30.0)
    try:
        refused = (
            rf"cannot link {path} to /dev/pts/\d+: it links to {first.path}, still open, most "
            r"likely another dronetrack emulate's \(give another path, or end that one\)$"
        )
        with pytest.raises(DeviceError, match=refused):
            PtyServoLink(turret_bus(), link=path, lifetime=30.0)
        assert os.readlink(path) == first.path
        assert _ping_through(path, 1) == 1020
    finally:
        first.close()
    assert not path.is_symlink()


def test_a_stale_link_is_replaced_and_a_link_taken_over_is_left_alone(tmp_path: Path) -> None:
    path, gone, other = tmp_path / "ttyDXL", tmp_path / "gone", tmp_path / "other"
    path.symlink_to(gone)  # an emulator's that ended without removing it
    served = PtyServoLink(turret_bus(), link=path, lifetime=30.0)
    try:
        assert os.readlink(path) == served.path
        path.unlink()
        path.symlink_to(other)  # since made by someone else
    finally:
        served.close()
    assert os.readlink(path) == str(other)


def test_the_serving_thread_stops_by_itself_after_its_lifetime() -> None:
    served = PtyServoLink(turret_bus(), lifetime=0.1, poll=0.01)
    deadline = time.monotonic() + 2.0
    while served.serving and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not served.serving
    served.close()


def test_the_rate_limited_joint_moves_at_its_rate() -> None:
    joint = RateLimitedJoint(0.0)
    joint.profile(units_to_rate(131), 0.0, 0.0)
    joint.goal(math.pi / 2, 1.0)
    w = units_to_rate(131)
    assert joint.position(1.0) == 0.0
    assert joint.position(1.5) == pytest.approx(0.5 * w)
    assert joint.velocity(1.5) == pytest.approx(w)
    assert joint.position(1.0 + (math.pi / 2) / w + 1e-9) == math.pi / 2
    assert joint.velocity(3.0) == 0.0
    joint.goal(0.0, 3.0)
    assert joint.position(3.25) == pytest.approx(math.pi / 2 - 0.25 * w)


def test_a_bus_refuses_two_servos_with_one_id() -> None:
    with pytest.raises(DeviceError, match="distinct IDs"):
        ServoBus([EmulatedXM430(1), EmulatedXM430(1)])
