"""``dronetrack emulate``: a scenario's simulator in real time behind an emulated LiDAR
(a Livox or a Velodyne VLP-16, UDP) and turret (pseudo-terminal: Dynamixel servos, or a
FLIR PTU for the PTU-E46 preset), or both on ROS 2 (--ros2), to test the live chain
without hardware."""

from __future__ import annotations

import ipaddress
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated

import typer

from dronetrack.cli.app import RunInterruptedError, app
from dronetrack.cli.options import (
    FlightDurationOption,
    RosDomainOption,
    ScenarioArgument,
    SeedOption,
    scenario_from_options,
)
from dronetrack.cli.output import err_console

if TYPE_CHECKING:
    from dronetrack.sim.emulate.rig import EmulatedRig

__all__ = ["emulate"]

POLL_S = 0.05  # how often the waiting command looks at Ctrl-C, SIGTERM and the rig
LINGER_S = 2.0  # the devices answer this long after the stream, while the host closes
WAIT_S = 600.0  # how long it waits for a host by default


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


def _print_ros2(device: object, options: object) -> None:
    """The two lines a host needs: the ros2:// URIs of the LiDAR and the turret."""
    from dronetrack.sim.emulate.ros2 import Ros2Device, Ros2Options

    assert isinstance(device, Ros2Device)
    assert isinstance(options, Ros2Options)
    tf = "/tf and /tf_static" if options.tf else "no /tf"
    typer.echo(
        f"lidar: ros2://{options.topic}  ({options.msg_type}, {options.frame_id}; {tf}; "
        f"ROS 2 domain {device.domain.domain_id})"
    )
    typer.echo(
        f"turret: ros2://{options.turret_ns}  (sensor_msgs/JointState goals on "
        f"{options.command_topic}, states on {options.states_topic})"
    )


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


def _serve(rig: EmulatedRig, stop: threading.Event, began: str, wait_s: float) -> bool | None:
    """Let the rig serve hosts until its run is over: True once the scenario clock, from
    the last start, has passed the streamed length and the stream has ended (a host that
    stopped sampling ended it), and ``LINGER_S`` more have passed while the host closes
    (stops sampling, parks the turret); False on a stop request; None if no host started
    the scenario within ``wait_s``.  Says each start."""
    from dronetrack.interrupt import stop_requested

    ready = streaming = time.monotonic()
    announced = 0
    while not (stop.is_set() or stop_requested()):
        now = time.monotonic()
        if rig.starts > announced:
            announced = rig.starts
            _say(f"{began}: the scenario clock runs")
        elapsed = rig.scenario_time(now)
        if rig.device.sampling:
            streaming = now
        if elapsed is None:
            if now - ready > wait_s:
                return None
        elif elapsed >= rig.duration_s + LINGER_S and now - streaming >= LINGER_S:
            return True
        time.sleep(POLL_S)
    return False


@app.command()
def emulate(
    scenario: ScenarioArgument = None,
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
            "Port settings).",
            show_default="127.0.0.1:2368 from a loopback --lidar-ip",
        ),
    ] = None,
    serial_link: Annotated[
        Path | None,
        typer.Option(
            "--serial-link",
            help="Also reach the turret's pseudo-terminal through this symlink "
            "(dynamixel://PATH, or ptu://PATH for a PTU-E46 scenario, opens it).",
        ),
    ] = None,
    ptu_baud: Annotated[
        int,
        typer.Option(
            "--ptu-baud",
            help="The emulated PTU's serial rate: its replies are paced as on a line at this "
            "baud (8N1); a PTU-E46 scenario only.",
        ),
    ] = 9600,
    truth: Annotated[
        Path | None,
        typer.Option(
            "--truth",
            help="Write the target's true position here: CSV t,x,y,z, t in the sensor's "
            "time base (seconds since sampling started, as the packets' stamps).",
        ),
    ] = None,
    ros2: Annotated[
        bool,
        typer.Option(
            "--ros2",
            help="Instead: publish on ROS 2 over DDS as livox_ros_driver2 (CustomMsg on "
            "/livox/lidar), /tf and /tf_static, and take goals on /turret/command "
            "(JointState), publishing /turret/joint_states (extra: ros2).",
        ),
    ] = False,
    ros_domain_id: RosDomainOption = None,
    wait_s: Annotated[
        float,
        typer.Option(
            "--wait-s",
            min=0.1,
            help="Seconds to wait for a host to start the scenario (start sampling, listen "
            "or subscribe); none came: error, exit code 2.",
        ),
    ] = WAIT_S,
    pointcloud2: Annotated[
        bool,
        typer.Option(
            "--pointcloud2",
            help="With --ros2: the points as a PointCloud2 (sensor_msgs; in the layout of "
            "livox_ros_driver2) instead of a CustomMsg.",
        ),
    ] = False,
    tf: Annotated[
        bool,
        typer.Option(
            "--tf/--no-tf",
            help="With --ros2: publish the turret's joints on /tf (--no-tf: the host takes "
            "the sensor's pose from the joint states).",
        ),
    ] = True,
) -> None:
    """Run a scenario's simulator in real time behind an emulated rig, to test 'live'
    without hardware.

    The LiDAR is a Livox on UDP (SDK 1 for the Avia and Mid-40, SDK 2 for the
    Mid-360) or a VLP-16 sending to --lidar-dest; the turret, on a pseudo-terminal, is
    two XM430 servos, or a FLIR PTU (ASCII commands) when the scenario's turret is the
    PTU-E46.  The scenario starts when a host starts sampling (a VLP-16: when a host
    listens): the background scan, then the flight, as simulate runs them.  With
    --ros2, both are ROS 2 topics instead, and the scenario starts when the point topic
    gets a subscriber.  A later start (after a host stopped) runs it again from its
    start, and the scenario clock starts again.

    Prints the devices' addresses, then waits for a host, at most --wait-s seconds
    (none came: exit 2).  It exits 0 2 s after the scenario clock of the last start has
    passed the length it says it streams (scan, flight and a 2-frame tail) and the
    stream has ended, whether the host sampled to the end or stopped before; Ctrl-C or
    SIGTERM end it sooner (exit 130; the truth file is kept).
    """
    from dronetrack.errors import ConfigError, DeviceError
    from dronetrack.formats.ptu import BAUD_RATES
    from dronetrack.interrupt import stoppable
    from dronetrack.jobs.emulate import emulated_rig, emulated_seconds
    from dronetrack.jobs.factory import scan_duration
    from dronetrack.realtime import frozen_heap
    from dronetrack.sim.emulate.lidars import DEVICES, host_uri

    try:
        ipaddress.IPv4Address(lidar_ip)
    except ValueError:
        raise ConfigError(f"--lidar-ip {lidar_ip!r} is not an IPv4 address") from None
    if ptu_baud not in BAUD_RATES:
        rates = ", ".join(map(str, BAUD_RATES))
        raise ConfigError(f"--ptu-baud {ptu_baud} is not a standard rate ({rates})")
    if not ros2 and (pointcloud2 or not tf or ros_domain_id is not None):
        raise ConfigError("--pointcloud2, --no-tf and --ros-domain-id go with --ros2")
    if ros2 and (serial_link is not None or lidar_dest is not None):
        raise ConfigError("--serial-link and --lidar-dest are for the UDP rig; --ros2 has neither")
    dest = _destination(lidar_dest) if lidar_dest is not None else None
    cfg = scenario_from_options(scenario, None, seed=seed, duration=duration)
    if dest is not None:
        known = DEVICES.get(cfg.sensor.model)
        if known is None or known.scheme != "velodyne":
            raise ConfigError("--lidar-dest is for a VLP-16; this scenario's LiDAR takes a host")
    options = None
    if ros2:
        from dronetrack.sim.emulate.ros2 import Ros2Options

        options = Ros2Options(pointcloud2=pointcloud2, tf=tf)
    rig = emulated_rig(
        cfg,
        lidar_ip=lidar_ip,
        serial_link=serial_link,
        truth=truth,
        lidar_dest=dest,
        ptu_baud=ptu_baud,
        ros2=options,
        ros_domain_id=ros_domain_id,
    )
    # What is built stays: no full collection of it pauses a slice (measured 45 ms, once
    # about every 2 s of stream, without this; under 10 ms with it).
    stop = threading.Event()
    with frozen_heap(), rig, _sigterm_sets(stop), stoppable():
        if options is not None:
            _print_ros2(rig.device, options)
            waits, began = "a subscriber of " + options.topic, "a subscriber came"
        else:
            model = DEVICES[cfg.sensor.model]
            ip, port = rig.address
            assert rig.link is not None
            uri = host_uri(model, rig.device)
            if model.scheme == "velodyne":
                wire = f"UDP from {ip}:{port} to {uri.removeprefix('velodyne://')}"
                waits, began = "a host to listen", "a host listens"
            else:
                wire = f"UDP {ip}:{port}"
                waits, began = "a host to start sampling", "sampling started"
            typer.echo(f"lidar: {uri}  ({model.name}, {wire})")
            if rig.ptu is not None:
                what = f"FLIR PTU-E46, {rig.ptu_baud} baud 8N1"
            else:
                rate = "/".join(map(str, sorted(rig.bus.rates())))
                what = f"2 XM430-W350, pan ID 1, tilt ID 2, {rate} baud"
            typer.echo(f"turret: {rig.turret_uri}  ({what}, on {rig.link.path})")
        sys.stdout.flush()
        scan_s = scan_duration(cfg.pipeline)
        _say(
            f"{cfg.name}: waiting for {waits}; then {scan_s:g} s of "
            f"background scan and {cfg.duration_s:g} s of flight "
            f"({emulated_seconds(cfg):g} s streamed)"
        )
        ended = _serve(rig, stop, began, wait_s)
        if ended is None:
            raise DeviceError(f"{cfg.name}: waited {wait_s:g} s for {waits}, none came (--wait-s)")
    device = rig.device
    what = "point messages" if options is not None else "point packets"
    kept = f"; truth ({rig.truth_rows} rows) kept in {truth}" if truth is not None else ""
    if not ended:
        raise RunInterruptedError(f"{kept}; {device.packets_sent} {what} sent")
    _say(
        f"streamed {rig.slices * rig.slice_s:.2f} s of {cfg.name}: "
        f"{device.packets_sent} {what}, {device.points_built} points"
        + (f"; truth: {rig.truth_rows} rows in {truth}" if truth is not None else "")
    )
