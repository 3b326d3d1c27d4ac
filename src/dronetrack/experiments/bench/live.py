"""The live chain on one machine, timed: latency and a memory soak.

Both run ``dronetrack emulate`` in its own process (the simulator in real time behind
an emulated Livox Avia on UDP at its full 240,000 points/s, or the LiDAR of another
scenario, e.g. a VLP-16's 754 packets/s, and two emulated XM430 servos on a
pseudo-terminal) on a loopback address of its own, and ``run_live`` in this process
against it through the real protocols, with the Dynamixel turret on the emulated
servos (or ``none``), writing ``frames.csv`` as ``dronetrack live`` does.
With ``turret="ptu"`` the scenario's turret is the PTU-E46 instead, and the emulator
serves a FLIR PTU on the pseudo-terminal, paced at ``ptu_baud`` (``ptu://``).
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

With ``chain`` "ros2" both run over ROS 2 instead: ``emulate --ros2`` (livox_ros_driver2's
CustomMsg on /livox/lidar, /tf, the turret on /turret/command and joint_states) on a
DDS domain of this process's own, and ``live --lidar ros2:///livox/lidar --turret
ros2:///turret`` (Cyclone reads ``CYCLONEDDS_URI`` in both processes).

These are benchmarks, not tests: the flight is flown at wall-clock speed and the
figures depend on the machine's load.  ``live_bench`` runs both with ``LiveSettings``
and returns the dictionary ``dronetrack bench --live`` writes as bench_live.json.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import ConfigError
from dronetrack.experiments.bench.c2 import BenchC2
from dronetrack.experiments.bench.emulator import (
    TURRETS,
    emulator_process,
    scenario_with_turret,
)
from dronetrack.experiments.bench.live_settings import (
    LATENCY_P99_TARGET_MS,
    LIVE_FULL,
    LIVE_TARGETS,
    RSS_GROWTH_TARGET_PCT,
    SAPIENT_PAIRS,
    LiveSettings,
)
from dronetrack.experiments.bench.machine import machine_info
from dronetrack.experiments.bench.memory import RssSampler, rss_growth_pct
from dronetrack.experiments.bench.suite import evaluate_targets

__all__ = [
    "LiveRunFigures",
    "live_bench",
    "live_latency",
    "live_soak",
    "run_against_emulator",
]

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
    turret_kind: str = "dynamixel",
    ptu_baud: int = 9600,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    sample_s: float | None = None,
    truth: bool = True,
    workdir: Path | None = None,
    progress: Progress | None = None,
    chain: str = "livox",
    sapient: bool = False,
) -> LiveRunFigures:
    """Emulate ``scenario`` (seed ``seed``) for ``flight_s`` seconds of flight and run
    ``live`` against it (the Dynamixel turret, or with ``turret_kind="ptu"`` the
    scenario with the PTU-E46 on an emulated FLIR PTU at ``ptu_baud``; ``none``
    without ``turret``) for as long after its background scan (the scenario's, or
    ``scan_s``), writing
    ``frames.csv`` in a temporary folder (in ``workdir``), scored against the
    emulator's truth if ``truth``; with ``sample_s``, resident memory every
    ``sample_s`` seconds; ``chain`` "ros2": over ROS 2 (``emulate --ros2``, ``live
    --lidar ros2:///livox/lidar --turret ros2:///turret``; no turret: ``none``); with
    ``sapient``, a site and a SAPIENT edge node sending to a fusion node of this
    process (``sapient_first_report_ms``: each track's first DetectionReport, from
    its frame's arrival to its receipt).  The device error that ended the run is
    raised."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.live.run import LiveSetup, live_config, run_live
    from dronetrack.jobs.run import RunFolder

    if not flight_s > 0:
        raise ConfigError(f"a live benchmark needs a flight of > 0 s, got {flight_s}")
    if turret_kind not in TURRETS:
        raise ConfigError(f"a live benchmark drives {' or '.join(TURRETS)}, not {turret_kind!r}")
    # the turret changes nothing of the scan: its length from the scenario as named
    background = live_config(get_scenario(scenario), scan_s=scan_s).pipeline.background
    total = (background.scan_s if background.enabled else 0.0) + flight_s
    sampler = RssSampler(sample_s) if sample_s is not None else None
    begin = [time.monotonic()]

    def started(_: object) -> None:
        begin[0] = time.monotonic()
        if sampler is not None:
            sampler.start()

    def frame_done(done: int, _: int) -> None:
        if progress is not None:
            progress(min(time.monotonic() - begin[0], total), total)

    with tempfile.TemporaryDirectory(dir=workdir, prefix="dronetrack-live-bench-") as tmp:
        named = scenario_with_turret(scenario, turret_kind, Path(tmp))
        cfg = live_config(get_scenario(named), duration_s=flight_s, scan_s=scan_s)
        folder = RunFolder(Path(tmp) / "run")
        # the fusion node killed once, after half the flight
        c2 = BenchC2(cfg, restart_after_s=0.5 * flight_s) if sapient else None
        with emulator_process(Path(tmp), named, seed, flight_s, ptu_baud, chain) as emu:
            setup = LiveSetup(
                emu.lidar,
                emu.turret if turret else "none",
                duration_s=flight_s,
                truth=emu.truth if truth else None,
                ros_domain_id=emu.ros_domain_id,
            )
            try:
                result = run_live(
                    c2.cfg if c2 is not None else cfg,
                    setup,
                    log_sink=folder.log_sink,
                    on_start=started,
                    progress=frame_done,
                    sinks=c2.sinks(folder) if c2 is not None else (),
                )
            finally:
                if sampler is not None:
                    sampler.stop()
                folder.close()
                if c2 is not None:
                    c2.close()
    wall = time.monotonic() - begin[0]
    if result.error is not None:
        raise result.error
    metrics = result.metrics()
    if c2 is not None:
        metrics.update(c2.figures())
    return LiveRunFigures(metrics, wall, sampler.samples if sampler is not None else [])


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
    turret_kind: str = "dynamixel",
    ptu_baud: int = 9600,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    workdir: Path | None = None,
    progress: Progress | None = None,
    chain: str = "livox",
    sapient: bool = False,
) -> dict[str, Any]:
    """The latency of a live run against the emulator (``run_against_emulator``):
    ``latency_ms_p50``, ``latency_ms_p99``, the frames logged and dropped, the packets
    lost, malformed and dropped, the turret's missed reads, coverage, and the p99
    target met or missed."""
    run = run_against_emulator(
        flight_s,
        turret=turret,
        turret_kind=turret_kind,
        ptu_baud=ptu_baud,
        scenario=scenario,
        seed=seed,
        scan_s=scan_s,
        workdir=workdir,
        progress=progress,
        chain=chain,
        sapient=sapient,
    )
    out = _figures(run, scenario=scenario, seed=seed, flight_s=flight_s, chain=chain)
    out.update({k: v for k, v in run.metrics.items() if k.startswith("sapient_")})
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
    turret_kind: str = "dynamixel",
    ptu_baud: int = 9600,
    scenario: str = "default",
    seed: int = 0,
    scan_s: float | None = None,
    workdir: Path | None = None,
    progress: Progress | None = None,
    chain: str = "livox",
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
        turret_kind=turret_kind,
        ptu_baud=ptu_baud,
        scenario=scenario,
        seed=seed,
        scan_s=scan_s,
        sample_s=sample_s,
        truth=False,
        workdir=workdir,
        progress=progress,
        chain=chain,
    )
    growth = rss_growth_pct(run.rss, warmup_s)
    after = [rss for t, rss in run.rss if t >= warmup_s]
    out = _figures(
        run,
        scenario=scenario,
        seed=seed,
        soak_s=soak_s,
        warmup_s=warmup_s,
        sample_s=sample_s,
        chain=chain,
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


def _with_sapient(
    plain: dict[str, Any],
    pairs: int,
    latency_run: Callable[[str, bool], dict[str, Any]],
) -> dict[str, Any]:
    """The latency run with SAPIENT on, ``pairs`` times, alternating with runs
    without it (``plain`` is the first of those; ``latency_run(what, sapient)`` makes
    one): one run's p99 moves by a few milliseconds from run to run, so the growth is
    the median p99 with SAPIENT less the median without.  The figures are the last
    SAPIENT run's, with ``p99_ms_runs`` and ``p99_plain_ms_runs`` and the
    ``p99_growth_ms``."""
    runs: dict[bool, list[dict[str, Any]]] = {False: [plain], True: []}
    for k in range(pairs):
        for on in (True, False) if k < pairs - 1 else (True,):
            what = f"live latency {'with' if on else 'without'} SAPIENT, run {k + 1} of {pairs}"
            runs[on].append(latency_run(what, on))
    p99 = {on: [r["latency_ms_p99"] for r in rs] for on, rs in runs.items()}
    out = dict(runs[True][-1])
    out["p99_ms_runs"] = p99[True]
    out["p99_plain_ms_runs"] = p99[False]
    known = all(v is not None for vs in p99.values() for v in vs)
    out["p99_growth_ms"] = float(np.median(p99[True]) - np.median(p99[False])) if known else None
    # each run's worst: the first report and the rejoin after the kill
    for key in ("sapient_first_report_ms_max", "sapient_reconnect_s", "frames_dropped"):
        values = [r[key] for r in runs[True]]
        out[key] = None if any(v is None for v in values) else max(values)
    return out


# --- both, for bench_live.json -----------------------------------------------------------


StageProgress = Callable[[str, float, float], None]  # (what, seconds run, seconds in all)


def live_bench(
    settings: LiveSettings = LIVE_FULL,
    *,
    quick: bool = False,
    turret: bool = True,
    progress: StageProgress | None = None,
    workdir: Path | None = None,
    chain: str = "livox",
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

    def latency_run(what: str, sapient: bool = False) -> dict[str, Any]:
        return live_latency(
            cfg.latency_s,
            turret=turret,
            turret_kind=cfg.turret,
            ptu_baud=cfg.ptu_baud,
            scenario=cfg.scenario,
            scan_s=cfg.scan_s,
            workdir=workdir,
            progress=stage(what),
            chain=chain,
            sapient=sapient,
        )

    latency = latency_run(f"live latency, {cfg.latency_s:g} s of flight")
    pairs = 1 if quick else SAPIENT_PAIRS
    with_c2 = _with_sapient(latency, pairs, latency_run) if cfg.sapient else None
    soak = None
    if cfg.soak_s > 0:
        soak = live_soak(
            cfg.soak_s,
            warmup_s=cfg.warmup_s,
            sample_s=cfg.sample_s,
            turret=turret,
            turret_kind=cfg.turret,
            ptu_baud=cfg.ptu_baud,
            scenario=cfg.scenario,
            scan_s=cfg.scan_s,
            workdir=workdir,
            progress=stage(f"live soak, {cfg.soak_s:g} s of flight"),
            chain=chain,
        )
    results: dict[str, Any] = {
        "machine": machine_info(),
        "settings": {
            **asdict(cfg),
            "quick": quick,
            # the turret driven: the emulated one of the chain, or none
            "turret": ("ros2" if chain == "ros2" else cfg.turret) if turret else "none",
            "chain": chain,
        },
        "live_latency": latency,
        "live_soak": soak,
        "live_latency_sapient": with_c2,
    }
    targets = [
        t
        for t in LIVE_TARGETS
        if (soak is not None or t.path[0] != "live_soak")
        and (with_c2 is not None or t.path[0] != "live_latency_sapient")
    ]
    results["targets"] = evaluate_targets(results, tuple(targets))
    return results
