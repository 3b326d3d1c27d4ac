"""``dronetrack info ptu://…`` against the emulated PTU-E46 on a pseudo-terminal and over
TCP, and its one error line when no unit answers."""

from __future__ import annotations

import os
import tty

import pytest

from dronetrack.cli.main import run
from dronetrack.config.rig import make_turret
from dronetrack.sim.emulate.ptu import FIRMWARE_BANNER, EmulatedPtu
from dronetrack.sim.emulate.ptu_link import PtyPtuLink, TcpPtuServer

E46 = make_turret("ptu-e46")


def test_info_of_an_emulated_ptu(capsys: pytest.CaptureFixture[str]) -> None:
    ptu = EmulatedPtu.from_turret(E46)
    with PtyPtuLink(ptu, lifetime=30.0) as link:
        ptu.handle("TP-388")  # 5° up
        assert run(["info", f"ptu://{link.device}"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"device: FLIR PTU on {link.device}, 9600 baud 8N1"
    assert out[1] == f"firmware: {FIRMWARE_BANNER}"
    # 46.44″ = 0.0129°; ±12325 positions = ±159.0°; 23255 positions/s = 300.0°/s
    assert out[2] == (
        "pan: resolution 46.44″ a position (0.0129°); limits -12325 to 12325 (-159.0° to "
        "159.0°); speed 23255 positions/s (300.0°/s, bound 23255); acceleration 23256 "
        "positions/s² (300.0°/s²); present position 0 (0.0°)"
    )
    assert out[3].startswith("tilt: resolution 46.44″ a position (0.0129°); limits -3643 to ")
    assert out[3].endswith("present position -388 (5.0°)")  # the turret's tilt: down > 0
    assert ptu.axes["P"].goal == 0  # nothing moved
    assert ptu.refused == 0


def test_info_over_tcp(capsys: pytest.CaptureFixture[str]) -> None:
    with TcpPtuServer(EmulatedPtu.from_turret(E46)) as server:
        host, port = server.address
        assert run(["info", server.uri]) == 0
    assert capsys.readouterr().out.splitlines()[0] == f"device: FLIR PTU at {host}:{port} (TCP)"


def test_info_of_a_silent_line_is_one_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    master, slave = os.openpty()  # a line with nothing at its other end
    tty.setraw(slave)
    path = os.ttyname(slave)
    try:
        assert run(["info", f"ptu://{path}"]) == 2
    finally:
        os.close(master)
        os.close(slave)
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: FLIR PTU on {path}: echo off: no answer at 9600 baud within 0.")
    assert "\n" not in err
    assert run(["info", "ptu:///dev/no-such-ptu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: FLIR PTU on /dev/no-such-ptu: cannot open the line: ")
