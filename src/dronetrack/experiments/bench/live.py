"""The live chain on one machine, timed: latency and a memory soak.

Both run ``dronetrack emulate`` in its own process (the simulator in real time behind
an emulated Livox Avia on UDP at its full 240,000 points/s, or the LiDAR of another
scenario, e.g. a VLP-16's 754 packets/s, and two emulated XM430 servos on a
pseudo-terminal) on a loopback address of its own, and ``run_live`` in this process
against it through the real protocols, with the Dynamixel turret on the emulated
servos (or ``none``), writing ``frames.csv`` as ``dronetrack live`` does.
The emulator is a separate process as a device is separate hardware: it shares the
machine's cores, not the host's interpreter.

- ``live_latency``: the issue's target, p99 of the latency from a frame's last
  firing (its arrival) to its turret command being sent, ≤ ``LATENCY_P99_TARGET_MS``;
  with ``latency_ms_p50``, ``frames_dropped``, ``packets_lost``, ``packets_malformed``
  and the turret's missed reads.  The run is scored against the emulator's truth.
- ``live_soak``: a long run (10 minutes of flight by default) whose resident memory
  is sampled every ``sample_s`` seconds from ``/proc/self/statm``; after ``warmup_s``
  seconds of the run (pools, caches and the first growths of the run's log settled)
  it must stay flat:

      growth = 100 · (max RSS after warm-up − RSS at the end of warm-up) / the latter

  ≤ ``RSS_GROWTH_TARGET_PCT``, with no packet lost and no frame dropped.  It runs as
  a rig does, without a truth file (whose rows a run keeps, as data, not a leak).

These are benchmarks, not tests: the flight is flown at wall-clock speed and the
figures depend on the machine's load.  ``live_bench`` runs both with ``LiveSettings``
and returns the dictionary ``dronetrack bench --live`` writes as bench_live.json.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.experiments.bench.machine import machine_info
from dronetrack.experiments.bench.suite import Target, evaluate_targets

__all__ = [
    "LATENCY_P99_TARGET_MS",
    "LIVE_FULL",
    "LIVE_QUICK",
    "LIVE_TARGETS",
    "RSS_GROWTH_TARGET_PCT",
    "EmulatorProcess",
    "LiveRunFigures",
    "LiveSettings",
    "emulator_process",
    "live_bench",
    "live_latency",
    "live_soak",
    "resident_mb",
    "rss_growth_pct",
    "run_against_emulator",
]

LATENCY_P99_TARGET_MS = 20.0  # issue 14: p99 ≤ 20 ms at the Avia's full point rate
RSS_GROWTH_TARGET_PCT = 5.0  # issue 14: resident memory flat after warm-up, ≤ 5 %
EMULATOR_START_S = 120.0  # emulate's start, compiling the simulator's kernels if not cached
EMULATOR_STOP_S = 10.0

LIVE_TARGETS: tuple[Target, ...] = (
    Target(("live_latency", "latency_ms_p99"), LATENCY_P99_TARGET_MS, "ms", "live latency p99"),
    Target(("live_soak", "rss_growth_pct"), RSS_GROWTH_TARGET_PCT, "%", "soak memory growth"),
    Target(("live_soak", "packets_lost"), 0.0, "packets", "soak packets lost"),
    Target(("live_soak", "frames_dropped"), 0.0, "frames", "soak frames dropped"),
)


# --- the emulator ------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class EmulatorProcess:
    """A running ``dronetrack emulate``: the URIs to open and its truth file."""

    proc: subprocess.Popen[bytes]
    lidar: str  # livox://IP with free host ports, or velodyne://IP:2368
    turret: str  # dynamixel://LINK
    truth: Path


def _loopback_ip() -> str:
    """A loopback address of this process's own (127.0.1.x), so that the emulator's
    fixed device port meets no other run's."""
    return f"127.0.1.{1 + os.getpid() % 250}"


def _read_lines(proc: subprocess.Popen[bytes], count: int, timeout_s: float) -> bytes:
    """The first ``count`` lines ``proc`` prints (fewer if it ends or the time is up)."""
    assert proc.stdout is not None
    out = b""
    deadline = time.monotonic() + timeout_s
    while out.count(b"\n") < count and time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.5)
        if ready:
            got = os.read(proc.stdout.fileno(), 4096)
            if not got:
                break
            out += got
    return out


@contextmanager
def emulator_process(
    workdir: Path, scenario: str = "default", seed: int = 0, flight_s: float = 20.0
) -> Iterator[EmulatorProcess]:
    """``dronetrack emulate SCENARIO --seed SEED --duration FLIGHT_S`` in its own
    process, once it has printed its two addresses; stopped (SIGTERM, then killed)
    on leaving.  Its messages go to ``workdir/emulate.log``.  A VLP-16 sends to port
    2368 of the emulator's own address.  DeviceError if it does not start within
    ``EMULATOR_START_S``."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.config.spinning import SPINNING

    ip = _loopback_ip()
    link, truth, log_path = workdir / "ttyDXL", workdir / "truth.csv", workdir / "emulate.log"
    args = [scenario, "--seed", str(seed), "--duration", f"{flight_s:g}", "--lidar-ip", ip]
    args += ["--serial-link", str(link), "--truth", str(truth)]
    velodyne = get_scenario(scenario).sensor.model in SPINNING
    if velodyne:
        args += ["--lidar-dest", f"{ip}:2368"]
    with log_path.open("wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "dronetrack", "emulate", *args],
            stdout=subprocess.PIPE,
            stderr=log,
        )
        try:
            if _read_lines(proc, 2, EMULATOR_START_S).count(b"\n") < 2:
                raise DeviceError(
                    f"dronetrack emulate did not start (exit {proc.poll()}); see {log_path}"
                )
            # host ports 0: free ones, so that no other live run on this machine is met
            lidar = f"livox://{ip}?cmd_port=0&data_port=0&broadcast_port=0"
            if velodyne:
                lidar = f"velodyne://{ip}:2368"
            yield EmulatorProcess(proc, lidar, f"dynamixel://{link}", truth)
        finally:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=EMULATOR_STOP_S)
                except subprocess.TimeoutExpired:
                    proc.kill()
            proc.wait(timeout=EMULATOR_STOP_S)
            if proc.stdout is not None:
                proc.stdout.close()


# --- resident memory ---------------------------------------------------------------------


def resident_mb() -> float:
    """This process's resident set size [MB] now (``/proc/self/statm``, Linux):
    resident pages × the page size.  ConfigError where there is no such file."""
    try:
        fields = Path("/proc/self/statm").read_text().split()
    except OSError as exc:
        raise ConfigError(f"the soak reads /proc/self/statm (Linux only): {exc}") from None
    return int(fields[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def rss_growth_pct(samples: list[tuple[float, float]], warmup_s: float) -> float:
    """Growth after warm-up [%]: 100 · (max RSS after it − RSS at its end) / RSS at its
    end, over (t [s since the run's start], RSS [MB]) samples; the end of warm-up is
    the first sample at or after ``warmup_s``.  ConfigError if there is none."""
    after = [rss for t, rss in samples if t >= warmup_s]
    if not after:
        raise ConfigError(f"no memory sample after the {warmup_s:g} s warm-up: soak longer")
    return 100.0 * (max(after) - after[0]) / after[0]


class _Sampler:
    """A daemon thread that samples ``resident_mb`` every ``period_s`` from ``start``."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.samples: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._t0 = 0.0
        self._thread = threading.Thread(target=self._loop, name="rss-sampler", daemon=True)

    def start(self) -> None:
        self._t0 = time.monotonic()
        self._thread.start()

    def _loop(self) -> None:
        while True:
            self.samples.append((time.monotonic() - self._t0, resident_mb()))
            if self._stop.wait(self.period_s):
                return

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)


# --- one live run --------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LiveRunFigures:
    """One live run against the emulator: its metrics, its wall time from the devices'
    answer to its end [s], and the memory samples (t [s since the devices answered],
    RSS [MB]) if asked for."""

    metrics: dict[str, Any]
    wall_s: float
    rss: list[tuple[float, float]]


Progress = Callable[[float, float], None]  # (seconds run, seconds in all)


def run_against_emulator(
    flight_s: float,
    *,
    turret: bool = True,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    sample_s: float | None = None,
    truth: bool = True,
    workdir: Path | None = None,
    progress: Progress | None = None,
) -> LiveRunFigures:
    """Emulate ``scenario`` (seed ``seed``) for ``flight_s`` seconds of flight and run
    ``live`` against it (the Dynamixel turret, or ``none`` without ``turret``) for as
    long after its background scan (the scenario's, or ``scan_s``), writing
    ``frames.csv`` in a temporary folder (in ``workdir``), scored against the
    emulator's truth if ``truth``; with ``sample_s``, resident memory every
    ``sample_s`` seconds.  The device error that ended the run is raised."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.live import LiveSetup, live_config, run_live
    from dronetrack.jobs.run import RunFolder

    if not flight_s > 0:
        raise ConfigError(f"a live benchmark needs a flight of > 0 s, got {flight_s}")
    cfg = live_config(get_scenario(scenario), duration_s=flight_s, scan_s=scan_s)
    background = cfg.pipeline.background
    total = (background.scan_s if background.enabled else 0.0) + flight_s
    sampler = _Sampler(sample_s) if sample_s is not None else None
    begin = [time.monotonic()]

    def started(_: object) -> None:
        begin[0] = time.monotonic()
        if sampler is not None:
            sampler.start()

    def frame_done(done: int, _: int) -> None:
        if progress is not None:
            progress(min(time.monotonic() - begin[0], total), total)

    with tempfile.TemporaryDirectory(dir=workdir, prefix="dronetrack-live-bench-") as tmp:
        folder = RunFolder(Path(tmp) / "run")
        with emulator_process(Path(tmp), scenario, seed, flight_s) as emu:
            setup = LiveSetup(
                emu.lidar,
                emu.turret if turret else "none",
                duration_s=flight_s,
                truth=emu.truth if truth else None,
            )
            try:
                result = run_live(
                    cfg, setup, log_sink=folder.log_sink, on_start=started, progress=frame_done
                )
            finally:
                if sampler is not None:
                    sampler.stop()
                folder.close()
    wall = time.monotonic() - begin[0]
    if result.error is not None:
        raise result.error
    return LiveRunFigures(result.metrics(), wall, sampler.samples if sampler is not None else [])


_LIVE_KEYS = ("latency_ms_p50", "latency_ms_p99", "frames", "frames_dropped", "packets_lost",
              "packets_malformed", "packets_dropped", "turret_reads_missed",
              "coverage_pct")  # fmt: skip


def _figures(run: LiveRunFigures, **settings: Any) -> dict[str, Any]:
    out: dict[str, Any] = {key: run.metrics.get(key) for key in _LIVE_KEYS}
    out.update(settings, turret=run.metrics.get("turret"), wall_s=run.wall_s)
    return out


def live_latency(
    flight_s: float = 20.0,
    *,
    turret: bool = True,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    workdir: Path | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """The latency of a live run against the emulator (``run_against_emulator``):
    ``latency_ms_p50``, ``latency_ms_p99``, the frames logged and dropped, the packets
    lost, malformed and dropped, the turret's missed reads, coverage, and the p99
    target met or missed."""
    run = run_against_emulator(
        flight_s,
        turret=turret,
        scenario=scenario,
        seed=seed,
        scan_s=scan_s,
        workdir=workdir,
        progress=progress,
    )
    out = _figures(run, scenario=scenario, seed=seed, flight_s=flight_s)
    p99 = out["latency_ms_p99"]
    out.update(
        target_p99_ms=LATENCY_P99_TARGET_MS,
        met=p99 is not None and p99 <= LATENCY_P99_TARGET_MS,
    )
    return out


def live_soak(
    soak_s: float = 600.0,
    *,
    warmup_s: float = 60.0,
    sample_s: float = 5.0,
    turret: bool = True,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    workdir: Path | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """A long live run against the emulator: ``soak_s`` seconds of flight after the
    scan, no truth file, resident memory every ``sample_s`` seconds; its growth after
    ``warmup_s`` seconds of the run (``rss_growth_pct``) with its target, the packets
    lost and frames dropped (both must be 0), the latency and the samples."""
    if not sample_s > 0:
        raise ConfigError(f"the soak's sampling period must be > 0 s, got {sample_s}")
    if not warmup_s >= 0:
        raise ConfigError(f"the soak's warm-up must be >= 0 s, got {warmup_s}")
    run = run_against_emulator(
        soak_s,
        turret=turret,
        scenario=scenario,
        seed=seed,
        scan_s=scan_s,
        sample_s=sample_s,
        truth=False,
        workdir=workdir,
        progress=progress,
    )
    growth = rss_growth_pct(run.rss, warmup_s)
    after = [rss for t, rss in run.rss if t >= warmup_s]
    out = _figures(
        run, scenario=scenario, seed=seed, soak_s=soak_s, warmup_s=warmup_s, sample_s=sample_s
    )
    out.update(
        rss_mb_warm=after[0],
        rss_mb_max=max(after),
        rss_mb_end=run.rss[-1][1],
        rss_growth_pct=growth,
        target_growth_pct=RSS_GROWTH_TARGET_PCT,
        met=bool(
            growth <= RSS_GROWTH_TARGET_PCT
            and out["packets_lost"] == 0
            and out["frames_dropped"] == 0
        ),
        rss_samples=[[t, mb] for t, mb in run.rss],
    )
    return out


# --- both, for bench_live.json -----------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LiveSettings:
    """How long each live measurement runs [s]: the latency run's flight, the soak's
    flight (0: no soak), its warm-up and sampling period, and the live side's
    background scan (None: the scenario's); and the scenario emulated (its LiDAR)."""

    latency_s: float = 20.0
    soak_s: float = 600.0
    warmup_s: float = 60.0
    sample_s: float = 5.0
    scan_s: float | None = None
    scenario: str = "default"

    def checked(self) -> LiveSettings:
        """These settings, or ConfigError naming the bad value."""
        if not self.latency_s > 0:
            raise ConfigError(f"the latency run needs a flight of > 0 s, got {self.latency_s}")
        if not self.soak_s >= 0:
            raise ConfigError(f"the soak must be >= 0 s (0: none), got {self.soak_s}")
        if self.soak_s > 0 and not 0 <= self.warmup_s < self.soak_s:
            raise ConfigError(
                f"the soak's warm-up must be >= 0 s and shorter than the soak "
                f"({self.soak_s:g} s), got {self.warmup_s}"
            )
        if not self.sample_s > 0:
            raise ConfigError(f"the soak's sampling period must be > 0 s, got {self.sample_s}")
        return self


LIVE_FULL = LiveSettings()
# a smoke test, not a measurement: a 0.5 s scan, 2 s of latency, a 4 s soak
LIVE_QUICK = LiveSettings(latency_s=2.0, soak_s=4.0, warmup_s=1.0, sample_s=0.5, scan_s=0.5)

StageProgress = Callable[[str, float, float], None]  # (what, seconds run, seconds in all)


def live_bench(
    settings: LiveSettings = LIVE_FULL,
    *,
    quick: bool = False,
    turret: bool = True,
    progress: StageProgress | None = None,
    workdir: Path | None = None,
) -> dict[str, Any]:
    """The latency run, then the soak (unless ``soak_s`` is 0); the contents of
    bench_live.json: the machine, the settings, ``live_latency``, ``live_soak`` (None
    without a soak) and each of ``LIVE_TARGETS`` met or missed."""
    cfg = settings.checked()

    def stage(what: str) -> Progress | None:
        if progress is None:
            return None
        report = progress
        return lambda done, total: report(what, done, total)

    latency = live_latency(
        cfg.latency_s,
        turret=turret,
        scenario=cfg.scenario,
        scan_s=cfg.scan_s,
        workdir=workdir,
        progress=stage(f"live latency, {cfg.latency_s:g} s of flight"),
    )
    soak = None
    if cfg.soak_s > 0:
        soak = live_soak(
            cfg.soak_s,
            warmup_s=cfg.warmup_s,
            sample_s=cfg.sample_s,
            turret=turret,
            scenario=cfg.scenario,
            scan_s=cfg.scan_s,
            workdir=workdir,
            progress=stage(f"live soak, {cfg.soak_s:g} s of flight"),
        )
    results: dict[str, Any] = {
        "machine": machine_info(),
        "settings": {**asdict(cfg), "quick": quick, "turret": turret},
        "live_latency": latency,
        "live_soak": soak,
    }
    targets = [t for t in LIVE_TARGETS if soak is not None or t.path[0] != "live_soak"]
    results["targets"] = evaluate_targets(results, tuple(targets))
    return results
