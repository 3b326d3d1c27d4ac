"""``dronetrack emulate``: a scenario's simulator in real time behind an emulated LiDAR
(a Livox or a Velodyne VLP-16, UDP) and turret (pseudo-terminal: Dynamixel servos, or a
FLIR PTU for the PTU-E46 preset), or both on ROS 2 (--ros2), to test the live chain
without hardware."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from dronetrack.cli.app import app
from dronetrack.cli.options import (
    FlightDurationOption,
    RosDomainOption,
    ScenarioArgument,
    SeedOption,
    scenario_from_options,
)
from dronetrack.cli.output import err_console

__all__ = ["emulate"]


def _say(text: str) -> None:
    err_console.print(text, markup=False, highlight=False, soft_wrap=True)


def _show(line: str) -> None:
    """A line a host needs (a device's URI), on stdout at once: scripts read it."""
    typer.echo(line)
    sys.stdout.flush()


_LidarIp = Annotated[
    str,
    typer.Option(
        "--lidar-ip",
        help="The emulated LiDAR's IPv4 address, one of this host's (127.0.0.1: loopback).",
    ),
]
_LidarDest = Annotated[
    str | None,
    typer.Option(
        "--lidar-dest",
        help="VLP-16 only: where it sends its packets, IP[:PORT] (its Host and Data "
        "Port settings).",
        show_default="127.0.0.1:2368 from a loopback --lidar-ip",
    ),
]
_SerialLink = Annotated[
    Path | None,
    typer.Option(
        "--serial-link",
        help="Also reach the turret's pseudo-terminal through this symlink "
        "(dynamixel://PATH, or ptu://PATH for a PTU-E46 scenario, opens it).",
    ),
]
_PtuBaud = Annotated[
    int,
    typer.Option(
        "--ptu-baud",
        help="The emulated PTU's serial rate: its replies are paced as on a line at this "
        "baud (8N1); a PTU-E46 scenario only.",
    ),
]
_Truth = Annotated[
    Path | None,
    typer.Option(
        "--truth",
        help="Write the target's true position here: CSV t,x,y,z, t in the sensor's "
        "time base (seconds since sampling started, as the packets' stamps).",
    ),
]
_Ros2 = Annotated[
    bool,
    typer.Option(
        "--ros2",
        help="Instead: publish on ROS 2 over DDS as livox_ros_driver2 (CustomMsg on "
        "/livox/lidar), /tf and /tf_static, and take goals on /turret/command "
        "(JointState), publishing /turret/joint_states (extra: ros2).",
    ),
]
_WaitS = Annotated[
    float,
    typer.Option(
        "--wait-s",
        min=0.1,
        help="Seconds to wait for a host to start the scenario (start sampling, listen "
        "or subscribe); none came: error, exit code 2.",
    ),
]
_PointCloud2 = Annotated[
    bool,
    typer.Option(
        "--pointcloud2",
        help="With --ros2: the points as a PointCloud2 (sensor_msgs; in the layout of "
        "livox_ros_driver2) instead of a CustomMsg.",
    ),
]
_Tf = Annotated[
    bool,
    typer.Option(
        "--tf/--no-tf",
        help="With --ros2: publish the turret's joints on /tf (--no-tf: the host takes "
        "the sensor's pose from the joint states).",
    ),
]


@app.command()
def emulate(
    scenario: ScenarioArgument = None,
    seed: SeedOption = None,
    duration: FlightDurationOption = None,
    lidar_ip: _LidarIp = "127.0.0.1",
    lidar_dest: _LidarDest = None,
    serial_link: _SerialLink = None,
    ptu_baud: _PtuBaud = 9600,
    truth: _Truth = None,
    ros2: _Ros2 = False,
    ros_domain_id: RosDomainOption = None,
    wait_s: _WaitS = 600.0,
    pointcloud2: _PointCloud2 = False,
    tf: _Tf = True,
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
    from dronetrack.jobs.emulate import EmulateOptions, emulate_scenario

    options = EmulateOptions(
        lidar_ip=lidar_ip,
        lidar_dest=lidar_dest,
        serial_link=serial_link,
        ptu_baud=ptu_baud,
        truth=truth,
        ros2=ros2,
        ros_domain_id=ros_domain_id,
        wait_s=wait_s,
        pointcloud2=pointcloud2,
        tf=tf,
    )
    cfg = scenario_from_options(scenario, None, seed=seed, duration=duration)
    done = emulate_scenario(cfg, options, show=_show, say=_say)
    kept = f"; truth: {done.truth_rows} rows in {truth}" if truth is not None else ""
    _say(
        f"streamed {done.streamed_s:.2f} s of {cfg.name}: {done.sent} {done.messages}, "
        f"{done.points} points{kept}"
    )
