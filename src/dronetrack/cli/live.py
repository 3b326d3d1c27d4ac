"""``dronetrack live``: the pipeline on a rig, a live LiDAR and a turret in the loop.

Registered on the ``dronetrack`` app by ``cli``; it follows its conventions: one
``error:`` line and exit code 2 for bad options and for a device that stops
answering (the run folder is kept), one ``interrupted`` line and exit code 130 for
Ctrl-C or SIGTERM (the turret holds, the files are written).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from dronetrack.cli.app import app, report_run, run_outputs, site_outputs
from dronetrack.cli.options import (
    SCENARIOS_OWN,
    ParticlesOption,
    PublishOption,
    RosDomainOption,
    RunDirOption,
    SapientOption,
    TrackerOption,
    scenario_from_options,
)
from dronetrack.cli.output import compile_reporter, err_console, progress_bar

if TYPE_CHECKING:
    from dronetrack.config.run import ScenarioConfig
    from dronetrack.seams import Sink

__all__ = ["live"]


def _say(text: str) -> None:
    err_console.print(text, markup=False, highlight=False, soft_wrap=True)


_DEVICES = """
LiDARs (--lidar): livox://IP (Avia, Mid-40/70, Horizon, Tele), livox2://IP (Mid-360),
velodyne://[IP:]PORT (VLP-16, e.g. velodyne://2368), ros2:///TOPIC (a ROS 2 PointCloud2
or livox_ros_driver2 CustomMsg topic, over DDS; keys type=, truth=/TOPIC, frame=), or
file://RECORDING (any recording track reads, played at wall-clock speed).

Turrets (--turret): dynamixel://DEVICE?baud=1000000&pan=1&tilt=2 (Dynamixel servos; the
keys are optional, these values their defaults), ptu://DEVICE?baud=9600 or
ptu://HOST:PORT (a FLIR pan-tilt unit), ros2:///NAMESPACE (goals as JointState on
NAMESPACE/command, or type=interbotix_xs_msgs/msg/JointGroupCommand; angles from
NAMESPACE/joint_states), or none (a fixed sensor).
"""
_Lidar = Annotated[
    str,
    typer.Option(
        "--lidar",
        metavar="<uri>",
        help="The LiDAR: livox://, livox2://, velodyne://, ros2:// or file:// (the "
        "LiDARs paragraph below).",
    ),
]
_Turret = Annotated[
    str,
    typer.Option(
        "--turret",
        metavar="<uri>",
        help="The turret: dynamixel://, ptu://, ros2:// or none (the Turrets paragraph below).",
    ),
]
_Scenario = Annotated[
    str | None,
    typer.Argument(
        help="A scenario name or a scenario/site .toml giving the rig and the pipeline; "
        "its scene and flight are ignored.",
        show_default="'default', or a file:// recording's own",
    ),
]
_Background = Annotated[
    Path | None,
    typer.Option("--background", help="Load this background model (.npz) instead of scanning."),
]
_ScanS = Annotated[
    float | None,
    typer.Option(
        "--scan-s", min=0.0, help="Seconds of background scan.", show_default=SCENARIOS_OWN
    ),
]
_Duration = Annotated[
    float | None,
    typer.Option(
        "--duration",
        "-d",
        min=0.01,
        help="Seconds of tracking after the background scan.",
        show_default="until Ctrl-C, or the end of a recording",
    ),
]
_Truth = Annotated[
    Path | None,
    typer.Option(
        "--truth",
        help="The target's true positions: CSV t,x,y,z, t in the sensor's time base; "
        "scores the run as simulate does.",
    ),
]
_FoxglovePort = Annotated[
    int | None,
    typer.Option(
        "--foxglove-port",
        min=1,
        max=65535,
        help="Serve the run live to the Foxglove app on this WebSocket port (extra: foxglove).",
    ),
]
_HostIp = Annotated[
    str | None,
    typer.Option(
        "--host-ip",
        help="This host's address the LiDAR sends to.",
        show_default="the one routed to it",
    ),
]


@app.command(epilog=_DEVICES)
def live(
    lidar: _Lidar,
    turret: _Turret,
    scenario: _Scenario = None,
    background: _Background = None,
    scan_s: _ScanS = None,
    duration: _Duration = None,
    truth: _Truth = None,
    out: RunDirOption = None,
    foxglove_port: _FoxglovePort = None,
    host_ip: _HostIp = None,
    tracker: TrackerOption = None,
    particles: ParticlesOption = None,
    ros_domain_id: RosDomainOption = None,
    publish: PublishOption = None,
    sapient: SapientOption = None,
) -> None:
    """Track live: scan the background with the turret, then detect, track and follow.

    Writes the same run folder as simulate (config.toml, frames.csv with each
    frame's latency_ms, metrics.json with the latency percentiles, frames dropped and
    packets lost, and the plots) and prints the metrics.
    """
    from dronetrack.config.run import apply_overrides
    from dronetrack.errors import DeviceError
    from dronetrack.interrupt import handling_sigterm
    from dronetrack.jobs.live.run import LiveSetup, base_config, live_config, run_live
    from dronetrack.jobs.site import run_folder

    setup = LiveSetup(lidar, turret, duration, truth, host_ip, ros_domain_id=ros_domain_id)
    named = scenario_from_options(scenario, None) if scenario is not None else None
    cfg = apply_overrides(base_config(named, lidar), tracker=tracker, particles=particles)
    cfg = live_config(cfg, duration_s=duration, background_file=background, scan_s=scan_s)
    folder = run_folder(out, cfg)
    with (
        _live_viewers(foxglove_port, cfg, publish, ros_domain_id) as viewers,
        handling_sigterm(),
        run_outputs(folder, None, None),
        site_outputs(cfg, folder, sapient) as site,
        progress_bar() as bar,
    ):
        task = bar.add_task("live", total=None)
        result = run_live(
            cfg,
            setup,
            progress=lambda i, n: bar.update(task, completed=i, total=None),
            sinks=[*viewers, *site],
            compiling=compile_reporter(bar, task),
            log_sink=folder.log_sink,
            on_start=lambda resolved: _say(_start_line(resolved, lidar, turret)),
            warn=lambda text: _say(f"warning: {text}"),
        )
    metrics = folder.finish(result.run, extra=result.metrics())
    if result.error is not None:
        raise DeviceError(
            f"{result.error} (turret stopped; {len(result.run.log)} frames kept in "
            f"{folder.out_dir})"
        )
    report_run(folder, result.run, metrics)


def _start_line(resolved: ScenarioConfig, lidar: str, turret: str) -> str:
    """The line said when the run starts: the devices, and the scan before tracking."""
    scan = resolved.pipeline.background
    scans = scan.enabled and scan.file is None and scan.scan_s > 0
    first = f"{scan.scan_s:g} s of background scan, then " if scans else ""
    return f"live: {lidar} with turret {turret}: {first}tracking; Ctrl-C stops"


@contextmanager
def _live_viewers(
    port: int | None, cfg: ScenarioConfig, publish: str | None, domain: int | None
) -> Iterator[list[Sink]]:
    """The live viewer server ``--foxglove-port`` asks for and ``--publish ros2``'s
    publisher (none without them), closed after the block."""
    from dronetrack.config.rig import turret_spec
    from dronetrack.jobs.site import site_view

    sinks: list[Sink] = []
    try:
        if publish is not None:
            from dronetrack.sinks.view import ViewerFeed
            from dronetrack.sinks.viewers import open_viewers

            feed = ViewerFeed(open_viewers(None, None, publish=publish, ros_domain_id=domain))
            sinks.append(feed)
        if port is not None:
            from dronetrack.sinks.foxglove.live import FoxgloveServer

            server = FoxgloveServer(port, turret_spec(cfg.turret).mount)
            view = site_view(cfg)
            if view is not None:
                server.show_site(view)
            _say(f"foxglove: {server.url}  (Foxglove app: Open connection, Foxglove WebSocket)")
            sinks.append(server)
        yield sinks
    finally:
        for sink in sinks:
            close = getattr(sink, "close", None)
            if close is not None:
                close()
