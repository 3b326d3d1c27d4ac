"""A live run on a rig (``dronetrack live``): a LiDAR stream and a turret in the loop.

    LiDAR ──packets──▶ LiveSource ──frame──▶ Pipeline.step ──command──▶ LimitGuard ──▶ turret
                           ▲                        └──result──▶ sinks (log, viewers)
                           └──────── time-stamped joint angles ─────────────────┘

The pipeline is the one ``simulate`` builds from the same configuration (the rig,
crop, field of regard, tracker, controller); a live run ignores the scenario's scene
and flight.  The run's clock starts at the first point (``sources.live``): the
turret scans the background for ``background.scan_s`` seconds of it (unless a
saved model is loaded), then the pipeline tracks until ``duration_s`` more have
passed, the stream ends (a ``file://`` recording) or the run is stopped.

The LiDAR: ``livox://IP`` (SDK 1), ``livox2://IP`` (SDK 2), ``velodyne://[IP:]PORT``
(a VLP-16, ``jobs.live.velodyne``: frames of one revolution or of the integration time, as
the scenario's sensor says), ``ros2:///TOPIC`` (``jobs.live.ros2``), or
``file://RECORDING``, any recording ``track`` reads, played at wall-clock speed
(``sources.paced``).  The turret: ``dynamixel://…``, ``ptu://…``, ``ros2:///…`` or
``none`` (``actuators.turrets``).

Ending.  A stop request (Ctrl-C, SIGTERM) ends the loop after the frame in hand: the
run is reported as interrupted.  A device error (a silent LiDAR, a servo that does
not answer) ends it at once; the run folder is still written with the frames done,
and the error is raised again for the command line to name.  Either way the turret
holds its present position and the LiDAR stops sampling before the run returns.
"""

from __future__ import annotations

import contextlib
import ipaddress
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dronetrack.actuators.turrets import FixedSensor, LimitGuard, check_turret_uri, open_turret
from dronetrack.config.rig import resolve_turret, target_spec, turret_spec
from dronetrack.config.run import ScenarioConfig
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.eval.log import TrackLog
from dronetrack.formats.ros.names import ROS2_SCHEME
from dronetrack.jobs.lidar_model import (
    FoundLidar,
    adopt_lidar,
    check_lidar_kind,
    livox_lidar,
    recording_lidar,
)
from dronetrack.jobs.live.streams import OPEN_TIMEOUT_S, OpenStream, open_point_stream
from dronetrack.jobs.replay import TARGET_MARGIN_M, recording_config
from dronetrack.jobs.run import RunResult, resolve_pipeline, run_seeds, turret_pipeline
from dronetrack.pipeline import run
from dronetrack.pipeline.kernels import CompileProgress, warm_up
from dronetrack.realtime import frozen_heap
from dronetrack.seams import Sink, Source
from dronetrack.sinks.track_log import TrackLogSink
from dronetrack.sources.live import Assembler, LiveSource
from dronetrack.sources.paced import FILE_SCHEME, PacedSource
from dronetrack.sources.recordings.kernels import REPLAY_WARM_UPS
from dronetrack.sources.truth_csv import TruthFile
from dronetrack.types import Sample

if TYPE_CHECKING:
    from dronetrack.jobs.live.ros2 import Ros2Link
    from dronetrack.sources.ros2.topic import Ros2Source

__all__ = [
    "LIDAR_SCHEMES",
    "LiveRun",
    "LiveSetup",
    "base_config",
    "live_config",
    "run_live",
]

Progress = Callable[[int, int], None]
LogSink = Callable[[TrackLog], None]
Warn = Callable[[str], None]
LIDAR_SCHEMES = ("livox://", "livox2://", "velodyne://", FILE_SCHEME, ROS2_SCHEME)


def _recording_path(uri: str) -> Path:
    path = Path(uri[len(FILE_SCHEME) :]).expanduser()
    if not str(path) or str(path) == ".":
        raise ConfigError(f"--lidar {uri!r} names no recording after file://")
    return path


def base_config(scenario: ScenarioConfig | None, lidar: str) -> ScenarioConfig:
    """The configuration a live run starts from: the SCENARIO or SITE.toml given; else,
    for ``file://RECORDING``, the scenario the recording carries (as ``track`` takes
    it), else the default scenario."""
    if scenario is not None:
        return scenario
    if lidar.startswith(FILE_SCHEME):
        from dronetrack.sources.recordings.opener import open_recording

        return recording_config(open_recording(_recording_path(lidar)), None)
    from dronetrack.config.scenarios import get_scenario

    return get_scenario("default")


def live_config(
    cfg: ScenarioConfig,
    *,
    duration_s: float | None = None,
    background_file: Path | None = None,
    scan_s: float | None = None,
) -> ScenarioConfig:
    """The scenario as a live run uses it: ``--background FILE`` or ``--scan-s SEC`` (not
    both) in its background section, ``--duration`` as its duration, the turret's
    preset written out; ConfigError for a controller a rig cannot run."""
    if background_file is not None and scan_s is not None:
        raise ConfigError("give --background or --scan-s, not both")
    if cfg.pipeline.controller.mode == "truth":
        raise ConfigError(
            "the 'truth' turret mode needs the simulator's true target; a live run takes "
            "tracking, fixed or a scan strategy"
        )
    if cfg.observer is not None:
        raise ConfigError("a live run has a turret on the ground, not an [observer]")
    bg = cfg.pipeline.background
    if background_file is not None:
        bg = bg.model_copy(update={"enabled": True, "file": str(background_file)})
    elif scan_s is not None:
        if not scan_s >= 0:
            raise ConfigError(f"--scan-s must be >= 0 s, got {scan_s}")
        bg = bg.model_copy(update={"enabled": scan_s > 0, "file": None, "scan_s": scan_s})
    pipeline = cfg.pipeline.model_copy(update={"background": bg})
    update: dict[str, Any] = {"pipeline": pipeline, "turret": resolve_turret(cfg.turret)}
    if duration_s is not None:
        update["duration_s"] = duration_s
    return cfg.model_copy(update=update)


@dataclass
class LiveSetup:
    """What a live run is asked to do (the command line's options)."""

    lidar: str
    turret: str = "none"
    duration_s: float | None = None  # tracking time after the background scan; None: no end
    truth: Path | None = None
    host_ip: str | None = None
    max_frames: int = 2  # the frame queue's bound (sources.live)
    ros_domain_id: int | None = None  # --ros-domain-id (None: ROS_DOMAIN_ID, else 0)
    ros_wait_s: float = 10.0  # how long a ros2:// topic has to show a publisher

    def __post_init__(self) -> None:
        if self.host_ip is not None:
            try:
                ipaddress.IPv4Address(self.host_ip)
            except ValueError:
                raise ConfigError(f"--host-ip {self.host_ip!r} is not an IPv4 address") from None


@dataclass(frozen=True, slots=True)
class LiveRun:
    """A finished live run: the run (as ``simulate`` gives it) and the live counters."""

    run: RunResult
    frames_dropped: int
    packets_lost: int
    packets_malformed: int
    packets_dropped: int  # the host's packet queue overflowed (the reader fell behind)
    commands_clamped: int  # commands the limit guard had to bring inside the limits
    turret_reads_missed: int  # the turret's polled reads that got no answer
    lidar: str
    turret: str
    error: DeviceError | None = None  # the device error that ended the run early

    def metrics(self) -> dict[str, Any]:
        """The run's metrics with the live ones (names are a contract): latency_ms_p50 and
        latency_ms_p99 (from the log), frames_dropped, packets_lost, packets_malformed,
        packets_dropped, commands_clamped, turret_reads_missed, lidar and turret."""
        out = self.run.metrics()
        out.update(
            frames_dropped=self.frames_dropped,
            packets_lost=self.packets_lost,
            packets_malformed=self.packets_malformed,
            packets_dropped=self.packets_dropped,
            commands_clamped=self.commands_clamped,
            turret_reads_missed=self.turret_reads_missed,
            lidar=self.lidar,
            turret=self.turret,
        )
        if self.error is not None:
            out["error"] = str(self.error)
        return out


def _frame_period(period: float, where: str) -> float:
    if not 1e-3 <= period <= 1.0:
        raise ConfigError(f"{where}: frame period {period:g} s is outside 1 ms to 1 s")
    return period


@contextmanager
def _turret(
    uri: str, cfg: ScenarioConfig, failed: list[DeviceError], domain_id: int | None = None
) -> Iterator[LimitGuard]:
    """The opened turret; on leaving, it holds its present position and lets go.  When
    the run already failed (an exception, or a device error in ``failed``), a failure to
    hold is not raised over it: the turret may be what failed."""
    guard = open_turret(uri, turret_spec(cfg.turret), ros_domain_id=domain_id)
    try:
        yield guard
    except BaseException:
        with contextlib.suppress(DeviceError):
            guard.close()
        raise
    if failed:
        with contextlib.suppress(DeviceError):
            guard.close()
    else:
        guard.close()


def run_live(
    cfg: ScenarioConfig,
    setup: LiveSetup,
    *,
    progress: Progress | None = None,
    sinks: Sequence[Sink] = (),
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
    on_start: Callable[[ScenarioConfig], None] | None = None,
    warn: Warn | None = None,
) -> LiveRun:
    """Run ``cfg``'s pipeline on the rig ``setup`` names (see the module docstring).

    ``cfg`` should come through ``live_config``.  The kernels are compiled (or loaded)
    before any device is opened; ``on_start`` is told the resolved configuration
    once both devices answer, with the sensor model the LiDAR or the recording says
    it is (``lidar_model``; ``warn`` is told when that is not the scenario's); a
    VLP-16 against a Livox scenario, or the other way round, is a ConfigError.
    ``sinks`` see every frame, the scan's too.  A device error after the devices
    opened ends the run early: the returned ``LiveRun`` holds it in ``error`` with
    the frames done (the caller writes them, then raises it).
    """
    lidar = setup.lidar
    if not lidar.startswith(LIDAR_SCHEMES):
        open_point_stream(lidar)  # raises the ConfigError that lists the schemes
    check_turret_uri(setup.turret)
    check_lidar_kind(cfg, lidar)
    truth = TruthFile(setup.truth) if setup.truth is not None else None
    radius = 0.5 * target_spec(cfg.drone.model).s_diag + TARGET_MARGIN_M
    stream: OpenStream | None = None
    assembler: Assembler | None = None
    ros2: Ros2Link | None = None
    if lidar.startswith(FILE_SCHEME):
        from dronetrack.sources.recordings.opener import open_recording

        recording = open_recording(_recording_path(lidar))
        cfg = _adopt(cfg, recording_lidar(recording), lidar, warn)
        period = _frame_period(recording.period, lidar)
    elif lidar.startswith(ROS2_SCHEME):
        from dronetrack.jobs.live.ros2 import Ros2Link

        ros2 = Ros2Link(lidar, setup.ros_domain_id)
        period = _frame_period(cfg.sensor.integration_time_s, "the scenario's sensor")
    else:
        stream = open_point_stream(lidar, setup.host_ip, cfg.sensor)
        period, assembler = cfg.sensor.integration_time_s, None
        if lidar.startswith("velodyne://"):
            from dronetrack.jobs.live.velodyne import velodyne_frames

            period, assembler = velodyne_frames(cfg.sensor)
        period = _frame_period(period, "the scenario's sensor")
    sensor = cfg.sensor.model_copy(update={"integration_time_s": period})
    cfg = resolve_pipeline(cfg.model_copy(update={"sensor": sensor}))
    spec = turret_spec(cfg.turret)
    _, filter_seed = run_seeds(cfg.seed)
    pipeline = turret_pipeline(cfg, period, spec, np.random.default_rng(filter_seed))
    kernels = warm_up(REPLAY_WARM_UPS, compiling)
    scan_s = pipeline.scan_until
    total_s = None if setup.duration_s is None else scan_s + setup.duration_s
    log = TrackLogSink(on_row=log_sink)
    failed: list[DeviceError] = []
    # No full collection of the start-up heap mid-run; the one that hides it runs
    # before any device streams, so no frame waits for it.
    with frozen_heap():
        try:
            with _turret(setup.turret, cfg, failed, setup.ros_domain_id) as turret:
                source: LiveSource | PacedSource | Ros2Source
                reader = None if isinstance(turret.turret, FixedSensor) else turret
                if ros2 is not None:
                    source = ros2.source(
                        spec.mount,
                        reader,
                        period_s=period,
                        max_frames=setup.max_frames,
                        duration_s=total_s,
                        truth_radius=radius,
                        truth=truth,
                        wait_s=setup.ros_wait_s,
                    )
                elif stream is None:
                    from dronetrack.sources.recordings.playback import RecordingSource

                    played: Source = RecordingSource(recording, radius)
                    if truth is not None:
                        played = _TruthOverride(played, truth, radius)
                    source = PacedSource(
                        played, max_frames=setup.max_frames, duration_s=total_s, name=lidar
                    )
                else:
                    stream.open(OPEN_TIMEOUT_S)
                    cfg = _adopt(cfg, _device_lidar(stream), lidar, warn)
                try:
                    if stream is not None:
                        source = LiveSource(
                            stream,
                            spec.mount,
                            reader,
                            period_s=period,
                            assembler=assembler,
                            max_frames=setup.max_frames,
                            duration_s=total_s,
                            truth=truth,
                            truth_radius=radius,
                        )
                    if on_start is not None:
                        on_start(cfg)
                    begin = time.perf_counter()
                    try:
                        stats = run(source, pipeline, turret, [log, *sinks], progress=progress)
                        interrupted = stats.interrupted
                    except DeviceError as exc:
                        failed.append(exc)
                        interrupted = False
                    wall = time.perf_counter() - begin
                finally:
                    if stream is not None:
                        stream.close()
        finally:
            if ros2 is not None:
                ros2.close()
    lost, malformed, dropped = _packet_counters(stream)
    if ros2 is not None:
        malformed = source.packets_malformed
    span = source.frames_delivered * period
    result = RunResult(cfg, log.log, pipeline, wall, span, kernels, interrupted)
    return LiveRun(
        result,
        source.frames_dropped,
        lost,
        malformed,
        dropped,
        turret.clamped,
        turret.reads_missed,
        lidar,
        setup.turret,
        failed[0] if failed else None,
    )


def _device_lidar(stream: OpenStream) -> FoundLidar | None:
    """What an opened Livox said it is in discovery (nothing for a VLP-16, whose client
    takes a VLP-16's packets only)."""
    from dronetrack.sources.livox.commands import LivoxCommands

    if not isinstance(stream, LivoxCommands):
        return None
    return livox_lidar(stream.dev_type, "from its discovery")


def _adopt(
    cfg: ScenarioConfig, found: FoundLidar | None, lidar: str, warn: Warn | None
) -> ScenarioConfig:
    """``cfg`` with the LiDAR's own model (``lidar_model.adopt_lidar``), ``warn`` told why."""
    cfg, warning = adopt_lidar(cfg, found, f"--lidar {lidar}")
    if warning is not None and warn is not None:
        warn(warning)
    return cfg


def _packet_counters(stream: OpenStream | None) -> tuple[int, int, int]:
    if stream is None:
        return 0, 0, 0
    return (
        int(stream.packets_lost),
        int(stream.packets_malformed),
        int(getattr(stream, "queue_dropped", 0)),
    )


class _TruthOverride:
    """A recording's frames with the ``--truth`` file as their truth (its t on the
    recording's clock)."""

    def __init__(self, source: Source, truth: TruthFile, radius: float) -> None:
        self.source = source
        self.truth = truth
        self.radius = radius

    @property
    def period(self) -> float:
        return float(self.source.period)

    def __iter__(self) -> Iterator[Sample]:
        from dronetrack.sources.truth import RecordedTruth

        for sample in self.source:
            g = self.truth.ground_truth()
            t = sample.frame.end
            truth = None if g is None else RecordedTruth(g, g.at(t)[0], self.radius)
            yield replace(sample, truth=truth)
