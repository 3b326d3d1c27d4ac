"""``dronetrack emulate``: a scenario's simulator in real time behind an emulated LiDAR
(a Livox or a Velodyne VLP-16, UDP) and Dynamixel turret (pseudo-terminal), to test the
live chain without hardware."""

from __future__ import annotations

import gc
import ipaddress
import math
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Annotated

import typer

from dronetrack.cli.app import RunInterruptedError, app
from dronetrack.cli.options import FlightDurationOption, SeedOption, scenario_from_options
from dronetrack.cli.output import err_console

__all__ = ["emulate"]

POLL_S = 0.05  # how often the waiting command looks at Ctrl-C, SIGTERM and the rig
LINGER_S = 2.0  # the devices answer this long after the stream, while the host closes


@contextmanager
def _sigterm_sets(stop: threading.Event) -> Iterator[None]:
    """SIGTERM sets ``stop`` inside the block (main thread only), as Ctrl-C asks a loop
    to stop; the previous handler comes back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _say(text: str) -> None:
    err_console.print(text, markup=False, highlight=False, soft_wrap=True)


def _destination(text: str) -> tuple[str, int]:
    """``IP[:PORT]`` (port 2368 if not given); ConfigError naming the problem."""
    from dronetrack.errors import ConfigError

    ip, colon, port = text.rpartition(":")
    if not colon:
        ip, port = text, "2368"
    try:
        ipaddress.IPv4Address(ip)
    except ValueError:
        raise ConfigError(f"--lidar-dest {text!r}: {ip!r} is not an IPv4 address") from None
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"--lidar-dest {text!r}: {port!r} is not a UDP port in 1..65535")
    return ip, int(port)


@app.command()
def emulate(
    scenario: Annotated[
        str | None,
        typer.Argument(help="A scenario name or .toml file (default: 'default')."),
    ] = None,
    seed: SeedOption = None,
    duration: FlightDurationOption = None,
    lidar_ip: Annotated[
        str,
        typer.Option(
            "--lidar-ip",
            help="The emulated LiDAR's IPv4 address, one of this host's (127.0.0.1: loopback).",
        ),
    ] = "127.0.0.1",
    lidar_dest: Annotated[
        str | None,
        typer.Option(
            "--lidar-dest",
            help="VLP-16 only: where it sends its packets, IP[:PORT] (its Host and Data "
            "Port settings; default 127.0.0.1:2368 from a loopback --lidar-ip).",
        ),
    ] = None,
    serial_link: Annotated[
        Path | None,
        typer.Option(
            "--serial-link",
            help="Also reach the servos' pseudo-terminal through this symlink "
            "(dynamixel://PATH opens it).",
        ),
    ] = None,
    truth: Annotated[
        Path | None,
        typer.Option(
            "--truth",
            help="Write the target's true position here: CSV t,x,y,z, t in the sensor's "
            "time base (seconds since sampling started, as the packets' stamps).",
        ),
    ] = None,
) -> None:
    """Run a scenario's simulator in real time behind an emulated rig, for testing
    'live' without hardware.

    The LiDAR is a Livox on UDP (SDK 1 for the Avia and Mid-40, SDK 2 for the
    Mid-360) or a VLP-16 sending to --lidar-dest; the turret is two XM430 servos on a
    pseudo-terminal.  The scenario starts when a host starts sampling (a VLP-16: when
    a host listens): the background scan, then the flight, as simulate runs them.
    Prints the devices' addresses, then runs until the scenario has been streamed, and
    2 s more while the host closes (exit 0), or until Ctrl-C or SIGTERM (exit 130; the
    truth file is kept).
    """
    from dronetrack.errors import ConfigError
    from dronetrack.interrupt import stop_requested, stoppable
    from dronetrack.jobs.emulate import emulated_rig, emulated_seconds
    from dronetrack.jobs.factory import scan_duration
    from dronetrack.sim.emulate.lidars import DEVICES, host_uri

    try:
        ipaddress.IPv4Address(lidar_ip)
    except ValueError:
        raise ConfigError(f"--lidar-ip {lidar_ip!r} is not an IPv4 address") from None
    dest = _destination(lidar_dest) if lidar_dest is not None else None
    cfg = scenario_from_options(scenario, None, seed=seed, duration=duration)
    model = DEVICES.get(cfg.sensor.model)
    if dest is not None and (model is None or model.scheme != "velodyne"):
        raise ConfigError("--lidar-dest is for a VLP-16; this scenario's LiDAR takes a host")
    rig = emulated_rig(
        cfg, lidar_ip=lidar_ip, serial_link=serial_link, truth=truth, lidar_dest=dest
    )
    model = DEVICES[cfg.sensor.model]
    # What is built stays: no full collection of it pauses a slice (measured 45 ms, once
    # about every 2 s of stream, without this; under 10 ms with it).
    gc.collect()
    gc.freeze()
    stop = threading.Event()
    with rig, _sigterm_sets(stop), stoppable():
        ip, port = rig.address
        assert rig.link is not None
        uri = host_uri(model, rig.device)
        velodyne = model.scheme == "velodyne"
        if velodyne:
            wire = f"UDP from {ip}:{port} to {uri.removeprefix('velodyne://')}"
            waits = "a host to listen"
        else:
            wire, waits = f"UDP {ip}:{port}", "a host to start sampling"
        typer.echo(f"lidar: {uri}  ({model.name}, {wire})")
        typer.echo(
            f"turret: dynamixel://{rig.serial_device}  (2 XM430-W350, pan ID 1, tilt ID 2, "
            f"on {rig.link.path})"
        )
        sys.stdout.flush()
        scan_s = scan_duration(cfg.pipeline)
        _say(
            f"{cfg.name}: waiting for {waits}; then {scan_s:g} s of "
            f"background scan and {cfg.duration_s:g} s of flight "
            f"({emulated_seconds(cfg):g} s streamed)"
        )
        announced = 0
        linger_until = math.inf
        while not (stop.is_set() or stop_requested()) and time.monotonic() < linger_until:
            if rig.starts > announced:
                announced = rig.starts
                began = "a host listens" if velodyne else "sampling started"
                _say(f"{began}: the scenario clock runs")
            if linger_until < math.inf:
                time.sleep(POLL_S)
            elif rig.finished.wait(POLL_S):
                # the host closes after its last frame: stop sampling, park the turret
                linger_until = time.monotonic() + LINGER_S
    device = rig.device
    kept = f"; truth ({rig.truth_rows} rows) kept in {truth}" if truth is not None else ""
    if not rig.finished.is_set():
        raise RunInterruptedError(f"{kept}; {device.packets_sent} point packets sent")
    _say(
        f"streamed {rig.slices * rig.slice_s:.2f} s of {cfg.name}: "
        f"{device.packets_sent} point packets, {device.points_built} points"
        + (f"; truth: {rig.truth_rows} rows in {truth}" if truth is not None else "")
    )
