"""Commands for recordings: ``track`` (replay), ``info`` and ``record``.

Registered on the ``dronetrack`` app by ``cli``; they follow its conventions
(one ``error:`` line and exit code 2 for anything the user can fix).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.table import Table

from dronetrack.cli.app import (
    app,
    report_run,
    run_outputs,
    site_outputs,
    stop_if_interrupted,
)
from dronetrack.cli.options import (
    ConfigOption,
    DroneOption,
    FlightDurationOption,
    FoxgloveOption,
    ParticlesOption,
    PublishOption,
    RerunOption,
    RosDomainOption,
    RunDirOption,
    SapientOption,
    ScenarioArgument,
    SeedOption,
    SensorOption,
    TrackerOption,
    TrajectoryOption,
    TurretOption,
    VisibilityOption,
    scenario_from_options,
)
from dronetrack.cli.output import (
    compile_reporter,
    err_console,
    print_kernel_note,
    print_metrics,
    progress_bar,
)
from dronetrack.cli.replay_options import (
    BackgroundFromOption,
    BackgroundOption,
    GtHeadingOption,
    GtOriginOption,
    GtTopicOption,
    LidarTopicOption,
    PeriodOption,
    PoseFrameOption,
    RecordingArgument,
    RecordingConfigOption,
    SensorPoseOption,
    TimestampsOption,
    TruthOption,
    replay_options,
)
from dronetrack.sources.recordings.opener import recording_info
from dronetrack.sources.recordings.recording import RecordingInfo, TopicInfo

if TYPE_CHECKING:
    from dronetrack.config.run import ScenarioConfig
    from dronetrack.jobs.record import RecordingPlan
    from dronetrack.jobs.replay import ReplayRun
    from dronetrack.jobs.run import RunFolder, RunResult
    from dronetrack.sources.recordings.recording import Recording, ReplayOptions

__all__ = ["info", "record", "track"]


def _warn(text: str) -> None:
    err_console.print(f"warning: {text}", markup=False, highlight=False, soft_wrap=True)


@app.command()
def track(
    recording: RecordingArgument,
    lidar_topic: LidarTopicOption = None,
    gt_topic: GtTopicOption = None,
    pose_frame: PoseFrameOption = None,
    background: BackgroundOption = None,
    background_from: BackgroundFromOption = None,
    tracker: TrackerOption = None,
    config: RecordingConfigOption = None,
    out: RunDirOption = None,
    sensor_pose: SensorPoseOption = None,
    gt_origin: GtOriginOption = None,
    gt_heading: GtHeadingOption = 0.0,
    period: PeriodOption = None,
    timestamps: TimestampsOption = None,
    truth: TruthOption = None,
    foxglove: FoxgloveOption = None,
    rerun: RerunOption = None,
    publish: PublishOption = None,
    ros_domain_id: RosDomainOption = None,
    sapient: SapientOption = None,
) -> None:
    """Replay a recording through the pipeline; turret commands are logged, not executed.

    Writes config.toml, frames.csv, commands.csv, metrics.json and plots, as simulate
    does; the metrics that need ground truth appear only when there is some.
    """
    from dronetrack.jobs.replay import run_replay
    from dronetrack.jobs.run import RunFolder
    from dronetrack.jobs.site import place, site_view
    from dronetrack.sinks.run_folder import default_run_dir

    folder = RunFolder(out if out is not None else default_run_dir())
    options = replay_options(
        lidar_topic, gt_topic, pose_frame, sensor_pose, gt_origin, gt_heading, period, timestamps
    )
    source, cfg = _open_replay(
        recording, options, truth, config, tracker, background, background_from
    )
    outputs = run_outputs(
        place(folder, cfg), foxglove, rerun, source.origin, publish, ros_domain_id, site_view(cfg)
    )
    site_feed = site_outputs(cfg, folder, sapient, steerable=False)
    with outputs as viewers, site_feed as site, progress_bar() as bar:
        task = bar.add_task(f"replaying {recording.name}", total=None)
        result = run_replay(
            source,
            cfg,
            progress=lambda i, n: bar.update(task, completed=i, total=n),
            viewers=viewers,
            sinks=site,
            compiling=compile_reporter(bar, task),
            log_sink=folder.log_sink,
            truth_file=truth,
        )
    _report_replay(folder, result)


def _open_replay(
    recording: Path,
    options: ReplayOptions,
    truth: Path | None,
    config: Path | None,
    tracker: str | None,
    background: Path | None,
    background_from: float | None,
) -> tuple[Recording, ScenarioConfig]:
    """``track``'s recording and configuration (``jobs.replay.open_replay``), with its
    warning said."""
    from dronetrack.jobs.replay import open_replay

    source, cfg, warning = open_replay(
        recording,
        options,
        truth=truth,
        config=config,
        tracker=tracker,
        background_file=background,
        background_from=background_from,
    )
    if warning is not None:
        _warn(warning)
    return source, cfg


def _report_replay(folder: RunFolder, result: ReplayRun) -> None:
    """``track``'s end: the run folder and commands.csv written, the replay's warnings,
    the run's report, then the messages it skipped."""
    from dronetrack.actuators.command_log import write_commands_csv

    metrics = folder.finish(result.run, extra=result.metrics())
    write_commands_csv(result.commands, folder.out_dir / "commands.csv")
    for warning in result.warnings:
        _warn(warning)
    report_run(folder, result.run, metrics)
    if result.skipped:
        err_console.print(
            "skipped messages: " + ", ".join(f"{k} {v}" for k, v in result.skipped.items())
        )


@app.command()
def info(
    target: Annotated[
        str,
        typer.Argument(
            metavar="RECORDING|DEVICE",
            help="A recording (see `dronetrack track --help`), or a live device: livox://IP, "
            "livox2://IP, velodyne://[IP:]PORT, dynamixel://DEVICE, ptu://DEVICE or "
            "ptu://HOST:PORT (with the query keys `dronetrack live --help` lists), or a ROS 2 "
            "domain (ros2://) or topic (ros2:///TOPIC).",
        ),
    ],
    ros_domain_id: RosDomainOption = None,
) -> None:
    """List a recording's topics, message types, counts and duration, or what a live
    device says of itself.

    A LiDAR: its model, code or serial, firmware and a short sample; a Dynamixel
    turret: its servos' model, firmware and present positions; a pan-tilt unit: its
    firmware, resolution, limits, speeds and positions.
    """
    from rich.markup import escape

    if target.startswith(("livox://", "livox2://", "velodyne://")):
        from dronetrack.jobs.live.probe import probe_lidar

        for name, value in probe_lidar(target):
            typer.echo(f"{name}: {value}")
        return
    if target.startswith("dynamixel://"):
        _servo_info(target)
        return
    if target.startswith("ros2://"):
        from dronetrack.jobs.live.ros2 import probe_ros2

        for name, value in probe_ros2(target, ros_domain_id):
            typer.echo(f"{name}: {value}")
        return
    if target.startswith("ptu://"):
        from dronetrack.actuators.ptu.probe import probe_ptu

        for name, value in probe_ptu(target):
            typer.echo(f"{name}: {value}")
        return
    recording = Path(target)
    summary = recording_info(recording)
    start = datetime.fromtimestamp(summary.start, tz=UTC).isoformat(timespec="milliseconds")
    title = f"{summary.path} ({summary.kind}, {summary.duration_s:.3f} s from {start})"
    table = Table(title=escape(title))
    table.add_column("topic")
    table.add_column("type")
    table.add_column("messages", justify="right")
    for topic in summary.topics:
        table.add_row(escape(topic.topic), escape(topic.msgtype), str(topic.count))
    Console().print(table)


def _servo_info(uri: str) -> None:
    """``info dynamixel://…``: one line per servo found; DeviceError if the turret's pan
    or tilt servo does not answer (after the lines), or if no servo answers at all."""
    import math

    from dronetrack.actuators.dynamixel.port import no_servo_answered
    from dronetrack.actuators.dynamixel.turret import parse_dynamixel_uri, probe_servos
    from dronetrack.errors import DeviceError

    reports = probe_servos(uri)
    if all(r.model is None for r in reports):  # not even the broadcast ping was answered
        where = parse_dynamixel_uri(uri)
        raise DeviceError(no_servo_answered(where.device, where.baud))
    missing = []
    for r in reports:
        head = f"servo ID {r.ident} ({r.role})"
        if r.problem is not None:
            typer.echo(f"{head}: {r.problem}")
            if r.role != "other":
                missing.append(f"ID {r.ident} ({r.role}): {r.problem}")
            continue
        line = f"{head}: model {r.model}, firmware {r.firmware}"
        if r.angle is not None:
            line += (
                f", present position {r.position} ({math.degrees(r.angle):.1f}°), "
                f"torque {'on' if r.torque else 'off'}, hardware error {r.hardware_error}"
            )
        typer.echo(line)
    if missing:
        raise DeviceError(f"Dynamixel turret {uri}: " + "; ".join(missing))


class RecordFormatName(StrEnum):
    ros1 = "ros1"
    ros2_sqlite3 = "ros2-sqlite3"
    ros2_mcap = "ros2-mcap"
    lvx = "lvx"
    lvx2 = "lvx2"


_RecordOut = Annotated[
    Path,
    typer.Option(
        "--out",
        "-o",
        help="The recording to write: NAME.bag (ROS 1), NAME.mcap or NAME.db3 (one ROS 2 "
        "file), NAME.lvx or NAME.lvx2 (Livox Viewer 1 or 2); without a suffix, a ROS 1 bag "
        "file, or a rosbag2 folder with a ros2 --format.",
    ),
]
_Format = Annotated[
    RecordFormatName | None,
    typer.Option(
        "--format",
        metavar="<container>",
        help=f"The container: {', '.join(f.value for f in RecordFormatName)}.",
        show_default="from the --out suffix, else ros1",
    ),
]
_LivoxCustom = Annotated[
    bool,
    typer.Option(
        "--livox-custom/--pointcloud2",
        help="Points as a Livox driver's CustomMsg (livox_ros_driver or "
        "livox_ros_driver2) or as a PointCloud2 (sensor_msgs).",
    ),
]
_Compress = Annotated[
    bool,
    typer.Option(
        "--compress",
        help="Compress: lz4 chunks (ROS 1), zstd chunks (MCAP), zstd messages (a rosbag2 "
        "sqlite3 folder).",
    ),
]


@app.command()
def record(
    out: _RecordOut,
    scenario: ScenarioArgument = None,
    fmt: _Format = None,
    livox_custom: _LivoxCustom = True,
    compress: _Compress = False,
    seed: SeedOption = None,
    duration: FlightDurationOption = None,
    tracker: TrackerOption = None,
    turret: TurretOption = None,
    particles: ParticlesOption = None,
    config: ConfigOption = None,
    trajectory: TrajectoryOption = None,
    visibility: VisibilityOption = None,
    drone: DroneOption = None,
    sensor: SensorOption = None,
) -> None:
    """Write a simulated closed-loop flight as the recording a real rig would make.

    A bag holds the LiDAR, /tf with the turret links, ground truth and the scenario,
    so `dronetrack track FILE` replays it with the same settings.  An LVX file holds
    the LiDAR's packets and its fixed pose (the turret holds still), with the truth
    and the scenario beside it.  Prints the metrics of the run, then what it wrote.
    """
    from dronetrack.jobs.record import prepare_recording
    from dronetrack.jobs.simulate import run_simulation

    cfg = scenario_from_options(
        scenario,
        config,
        seed=seed,
        duration=duration,
        trajectory=trajectory,
        visibility=visibility,
        drone=drone,
        sensor=sensor,
        tracker=tracker,
        particles=particles,
    )
    plan = prepare_recording(
        cfg,
        out,
        fmt.value if fmt is not None else None,
        turret_mode=turret.value if turret else None,
        livox_custom=livox_custom,
        compress=compress,
    )
    try:
        with progress_bar() as bar:
            task = bar.add_task(f"recording {cfg.name}", total=None)
            run = run_simulation(
                plan.resolved,
                progress=lambda i, n: bar.update(task, completed=i, total=n),
                sinks=[plan.writer],
                compiling=compile_reporter(bar, task),
            )
    finally:
        plan.writer.close()
    _report_recording(out, plan, run)


def _report_recording(out: Path, plan: RecordingPlan, run: RunResult) -> None:
    """``record``'s end: the kernels' note, then one ``interrupted`` line (exit 130),
    or the metrics, the recording written and its topics."""
    from dronetrack.sinks.lvx_writer import LvxWriter

    print_kernel_note(run.kernels)
    written = recording_info(out)
    writer = plan.writer
    lvx_frames = writer.frames_written if isinstance(writer, LvxWriter) else None
    summary = recording_summary(written, plan.container, writer.compression, lvx_frames)
    stop_if_interrupted(run.interrupted, f"; kept {summary}")
    print_metrics(run.metrics(), out)
    typer.echo(f"wrote {summary}")
    _print_topics(written.topics)
    if isinstance(writer, LvxWriter):
        typer.echo("  " + writer.replay_hint(plan.resolved.sensor.integration_time_s))


def recording_summary(
    info: RecordingInfo, container: str, compression: str | None, lvx_frames: int | None = None
) -> str:
    """One line on a written recording: path, container, frames (or LVX frames), length, size."""
    from dronetrack.sinks.bag_writer import FORMAT_NAMES, LIDAR_TOPIC

    path = info.path
    frames = sum(t.count for t in info.topics if t.topic == LIDAR_TOPIC)
    counted = f"{frames} frames" if lvx_frames is None else f"{lvx_frames} frames of 50 ms"
    files = [p for p in path.rglob("*") if p.is_file()] if path.is_dir() else [path]
    size = sum(p.stat().st_size for p in files)
    packing = f", compressed ({compression})" if compression else ""
    return (
        f"{path}: {FORMAT_NAMES[container]}{packing}, {counted}, "
        f"{info.duration_s:.1f} s, {size / 1e6:.1f} MB"
    )


def _print_topics(topics: Sequence[TopicInfo]) -> None:
    width = max(len(t.topic) for t in topics)
    type_width = max(len(t.msgtype) for t in topics)
    for t in topics:
        typer.echo(f"  {t.topic:<{width}}  {t.msgtype:<{type_width}}  {t.count:>7}")
