"""``dronetrack bench``: the benchmark suite on one core, its table and bench.json;
with ``--live``, the live chain against the emulator instead, and bench_live.json.

Registered on the ``dronetrack`` app by ``cli``; it follows its conventions (one
``error:`` line and exit code 2 for anything the user can fix).  The measuring is
``dronetrack.experiments.bench``'s; this module pins the thread pools, shows progress on
standard error, prints the table on standard output and writes the file.

One core: ``dronetrack.experiments.bench.single_thread`` sets numba's thread count with
``numba.set_num_threads(1)`` and every loaded BLAS/OpenMP pool's with threadpoolctl,
and restores them afterwards.  The environment variables (NUMBA_NUM_THREADS, ...)
are deliberately left alone: numpy and numba are loaded by then, and numba re-reads
its environment at every compilation, so changing NUMBA_NUM_THREADS after its
threads have started makes the next compilation fail (on a fresh install, with an
empty kernel cache, that is the first measurement).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich import box
from rich.console import Console
from rich.table import Table

from dronetrack.cli.app import app
from dronetrack.cli.options import RunDirOption
from dronetrack.cli.output import progress_bar
from dronetrack.experiments.bench import FULL, LIVE_FULL, LIVE_QUICK, QUICK
from dronetrack.experiments.bench.replay import MIN_REPLAY_S

if TYPE_CHECKING:
    from dronetrack.experiments.bench import LiveRequest

__all__ = ["bench", "bench_table", "live_table"]


def _with_quick(full: float, quick: float, unit: str = "") -> str:
    """An option's default as its help shows it: the full run's, then --quick's."""
    return f"{full:g}{unit}; {quick:g}{unit} with --quick"


def _target_cells(targets: dict[str, Any], key: str) -> tuple[str, str]:
    """The target column and the verdict of the measurement ``key`` (none: blank)."""
    target = targets.get(key)
    if target is None:
        return "", ""
    verdict = "[green]met[/green]" if target["met"] else "[bold red]MISSED[/bold red]"
    return f"≤ {target['limit']:g}", verdict


def bench_table(results: dict[str, Any], path: Path) -> Table:
    """The table ``dronetrack bench`` prints: the machine in the title, then every
    measurement with its statistics [ms] and, where it has one, its target."""
    m = results["machine"]
    s = results["settings"]
    quick = " (quick: a smoke test, not a measurement)" if s["quick"] else ""
    table = Table(
        title=(
            f"dronetrack bench: {m['cpu']}, {m['cores']} cores; Python {m['python']}, "
            f"numpy {m['numpy']}, numba {m['numba']}; one thread"
        ),
        caption=(
            f"times in ms, replay in multiples of real time; best of {s['rounds']} round(s) "
            f"of {s['repeats']} timed steps{quick}; {path}"
        ),
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    table.add_column("measurement", no_wrap=True)
    for name in ("median", "mean", "std", "max", "target", ""):
        table.add_column(name, justify="right", no_wrap=True)
    targets = results["targets"]

    def add(label: str, row: dict[str, float], key: str) -> None:
        values = [f"{row[k]:.2f}" for k in ("median", "mean", "std", "max")]
        table.add_row(label, *values, *_target_cells(targets, key))

    for n, row in results["pf_step_ms"].items():
        add(f"pipeline, {int(n):,} particles", row, f"pf_step_ms.{n}.median")
    multi = results["multi_step_ms"]
    add(f"pipeline, {multi['tracks']} tracks", multi, "")
    cells = _target_cells(targets, "multi_step_ms.p99")
    table.add_row(f"  {multi['clusters']} clusters: p99", f"{multi['p99']:.2f}", "", "", "", *cells)
    lm = results["learning_map"]
    cells = _target_cells(targets, "learning_map.peak_mb")
    table.add_row(
        "learning map [MB]",
        f"{lm['peak_mb']:.1f}",
        "",
        "",
        "",
        *cells,
    )
    table.add_section()
    for kind, row in results["tracker_step_ms"].items():
        add(f"tracker, {kind}", row, "")
    table.add_section()
    for sensor, row in results["sim_frame_stats_ms"].items():
        add(f"sim frame, {sensor}", row, f"sim_frame_ms.{sensor}")
    table.add_section()
    for key, row in results["replay_formats"].items():
        table.add_row(f"replay, {key}", f"{row['x_realtime']:.1f}×")
    table.add_row("replay, the slower", f"{results['replay_x_realtime']:.1f}×")
    return table


def _cell(value: Any, unit: str = "") -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.2f}{unit}"
    return f"{value}{unit}"


def _lidar_of(scenario: str) -> str:
    if scenario == "default":
        return "the Avia at 240,000 points/s"
    return f"the LiDAR of {scenario}"


def live_table(results: dict[str, Any], path: Path) -> Table:
    """The table ``dronetrack bench --live`` prints: the machine in the title, then each
    figure of the latency run and the soak with its target, where it has one."""
    m = results["machine"]
    s = results["settings"]
    quick = " (quick: a smoke test, not a measurement)" if s["quick"] else ""
    table = Table(
        title=(
            f"dronetrack bench --live: {m['cpu']}, {m['cores']} cores; Python {m['python']}; "
            f"emulate and live on loopback, {_lidar_of(s.get('scenario', 'default'))}"
            + (" over ROS 2 (DDS)" if s.get("chain") == "ros2" else "")
        ),
        caption=f"as dronetrack live runs (threads not pinned){quick}; {path}",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    table.add_column("measurement", no_wrap=True)
    for name in ("value", "target", ""):
        table.add_column(name, justify="right", no_wrap=True)
    targets = results["targets"]

    def add(label: str, row: dict[str, Any], key: str, unit: str, section: str) -> None:
        table.add_row(label, _cell(row[key], unit), *_target_cells(targets, f"{section}.{key}"))

    lat = results["live_latency"]
    turrets = {"none": "no turret", "dynamixel": "Dynamixel turret", "ros2": "ROS 2 turret"}
    turret = turrets.get(s["turret"], f"FLIR PTU-E46 at {s['ptu_baud']} baud")
    table.add_row(f"latency run: {lat['flight_s']:g} s of flight, {turret}", "", "", "")
    for label, key, unit in (
        ("latency p50", "latency_ms_p50", " ms"),
        ("latency p99", "latency_ms_p99", " ms"),
        ("frames", "frames", ""),
        ("frames dropped", "frames_dropped", ""),
        ("packets lost", "packets_lost", ""),
        ("packets malformed", "packets_malformed", ""),
        ("turret reads missed", "turret_reads_missed", ""),
        ("coverage", "coverage_pct", " %"),
    ):
        add(f"  {label}", lat, key, unit, "live_latency")
    soak = results["live_soak"]
    if soak is not None:
        table.add_section()
        table.add_row(
            f"soak: {soak['soak_s']:g} s of flight, RSS every {soak['sample_s']:g} s "
            f"after {soak['warmup_s']:g} s",
            "",
            "",
            "",
        )
        for label, key, unit in (
            ("RSS at the end of warm-up", "rss_mb_warm", " MB"),
            ("RSS max after warm-up", "rss_mb_max", " MB"),
            ("RSS growth", "rss_growth_pct", " %"),
            ("packets lost", "packets_lost", ""),
            ("frames dropped", "frames_dropped", ""),
            ("latency p50", "latency_ms_p50", " ms"),
            ("latency p99", "latency_ms_p99", " ms"),
            ("turret reads missed", "turret_reads_missed", ""),
        ):
            add(f"  {label}", soak, key, unit, "live_soak")
    c2 = results.get("live_latency_sapient")
    if c2 is not None:
        table.add_section()
        table.add_row("latency run again, with SAPIENT", "", "", "")
        for label, key, unit in (
            ("latency p99", "latency_ms_p99", " ms"),
            ("p99 growth, median of runs", "p99_growth_ms", " ms"),
            ("feed time per frame, p99", "sapient_sink_ms_p99", " ms"),
            ("first report, max", "sapient_first_report_ms_max", " ms"),
            ("first report, median", "sapient_first_report_ms_median", " ms"),
            ("frames dropped", "frames_dropped", ""),
            ("messages sent", "sapient_sent", ""),
            ("messages dropped", "sapient_dropped", ""),
            ("fusion node killed: rejoined", "sapient_reconnect_s", " s"),
        ):
            add(f"  {label}", c2, key, unit, "live_latency_sapient")
    return table


def _suite(out_dir: Path, quick: bool, **settings: Any) -> None:
    """``bench``: run the suite on one core, write bench.json, print the table."""
    from dronetrack.experiments.bench import bench as run_bench
    from dronetrack.experiments.bench import single_thread

    with single_thread(), progress_bar() as bar:
        task = bar.add_task("benchmarks", total=None)

        def report(what: str, done: int, total: int) -> None:
            bar.update(task, description=what, completed=done, total=total)

        results = run_bench(quick=quick, progress=report, **settings)
    _write(out_dir / "bench.json", results, bench_table)


def _live(out_dir: Path, request: LiveRequest, quick: bool) -> None:
    """``bench --live``: run the live benchmarks, write bench_live.json, print the table."""
    from dronetrack.experiments.bench import live_bench

    with progress_bar() as bar:
        task = bar.add_task("live benchmarks", total=None)

        def report(what: str, done: float, total: float) -> None:
            bar.update(task, description=what, completed=done, total=total)

        results = live_bench(
            request.settings,
            quick=quick,
            turret=request.turret,
            progress=report,
            chain=request.chain,
        )
    _write(out_dir / "bench_live.json", results, live_table)


def _write(
    path: Path, results: dict[str, Any], table: Callable[[dict[str, Any], Path], Table]
) -> None:
    """Write the results as JSON, print their table, then the file's path."""
    from dronetrack.sinks.run_folder import prepare_run_dir

    prepare_run_dir(path.parent)
    path.write_text(json.dumps(results, indent=2, allow_nan=False) + "\n")
    Console().print(table(results, path))
    typer.echo(str(path))


_QUICK_HELP = (
    f"A smoke test: {QUICK.repeats} steps, {QUICK.rounds} round, a {QUICK.replay_s:g} s "
    f"recording, unless given (with --live: {LIVE_QUICK.latency_s:g} s of latency, a "
    f"{LIVE_QUICK.soak_s:g} s soak)."
)
_Rounds = Annotated[
    int | None,
    typer.Option(
        "--rounds",
        min=1,
        help="Rounds per measurement; the best counts.",
        show_default=_with_quick(FULL.rounds, QUICK.rounds),
    ),
]
_Repeats = Annotated[
    int | None,
    typer.Option(
        "--repeats",
        min=1,
        help="Timed steps or frames per round (a fifth at 100,000 particles).",
        show_default=_with_quick(FULL.repeats, QUICK.repeats),
    ),
]
_ReplaySeconds = Annotated[
    float | None,
    typer.Option(
        "--replay-seconds",
        help=f"Length of the replayed recording, at least {MIN_REPLAY_S:g} s.",
        show_default=_with_quick(FULL.replay_s, QUICK.replay_s, " s"),
    ),
]
_Quick = Annotated[bool, typer.Option("--quick", help=_QUICK_HELP)]
_Live = Annotated[
    bool,
    typer.Option(
        "--live",
        help="Instead: the live chain against 'dronetrack emulate' in real time "
        "(latency, then a memory soak); writes bench_live.json.",
    ),
]
_LatencyS = Annotated[
    float | None,
    typer.Option(
        "--latency-s",
        help="With --live: the latency run's flight.",
        show_default=_with_quick(LIVE_FULL.latency_s, LIVE_QUICK.latency_s, " s"),
    ),
]
_SoakS = Annotated[
    float | None,
    typer.Option(
        "--soak-s",
        help="With --live: the soak's flight, 0 for none.",
        show_default=_with_quick(LIVE_FULL.soak_s, LIVE_QUICK.soak_s, " s"),
    ),
]
_WarmupS = Annotated[
    float | None,
    typer.Option(
        "--warmup-s",
        help="With --live: the soak's warm-up before memory counts.",
        show_default=_with_quick(LIVE_FULL.warmup_s, LIVE_QUICK.warmup_s, " s"),
    ),
]
_Turret = Annotated[
    str | None,
    typer.Option(
        "--turret",
        help="With --live: the emulated turret driven, dynamixel (the scenario's WidowX), "
        "ptu (a FLIR PTU-E46 on its ASCII line) or none (a fixed sensor).",
        show_default=LIVE_FULL.turret,
    ),
]
_PtuBaud = Annotated[
    int | None,
    typer.Option(
        "--ptu-baud",
        help="With --live --turret ptu: the line's baud rate.",
        show_default=str(LIVE_FULL.ptu_baud),
    ),
]
_Scenario = Annotated[
    str | None,
    typer.Option(
        "--scenario",
        help="With --live: the scenario emulated, and so its LiDAR (e.g. walk-line for a VLP-16).",
        show_default=repr(LIVE_FULL.scenario),
    ),
]
_Ros2 = Annotated[
    bool,
    typer.Option(
        "--ros2",
        help="With --live: over ROS 2 (emulate --ros2; live --lidar ros2:///livox/lidar "
        "--turret ros2:///turret, on a DDS domain of its own) instead of the Livox and "
        "Dynamixel protocols.",
    ),
]

_Sapient = Annotated[
    bool,
    typer.Option(
        "--sapient",
        help="With --live: latency runs with a SAPIENT edge node sending to a fusion node "
        "on loopback (killed and restarted half-way), alternating with runs without it "
        "(3, --quick 1); times its first reports (extra: sapient).",
    ),
]


@app.command()
def bench(
    out: RunDirOption = None,
    rounds: _Rounds = None,
    repeats: _Repeats = None,
    replay_seconds: _ReplaySeconds = None,
    quick: _Quick = False,
    live: _Live = False,
    latency_s: _LatencyS = None,
    soak_s: _SoakS = None,
    warmup_s: _WarmupS = None,
    turret: _Turret = None,
    ptu_baud: _PtuBaud = None,
    scenario: _Scenario = None,
    ros2: _Ros2 = False,
    sapient: _Sapient = False,
) -> None:
    """Time the pipeline, every tracker, the simulator and replay on one core.

    Writes bench.json (pf_step_ms, tracker_step_ms, sim_frame_ms, replay_x_realtime,
    machine, targets) and prints a table that marks each speed target met or missed.
    With --live, runs the live chain against the emulator instead (latency p50/p99,
    frames dropped, packets lost; a memory soak) and writes bench_live.json.
    """
    from dronetrack.experiments.bench import check_mode, live_request
    from dronetrack.sinks.run_folder import check_run_dir, default_run_dir

    out_dir = check_run_dir(out if out is not None else default_run_dir())
    suite = {"repeats": repeats, "rounds": rounds, "replay_s": replay_seconds}
    live_only = (latency_s, soak_s, warmup_s, turret, ptu_baud, scenario)
    check_mode(
        live,
        suite_options=any(v is not None for v in suite.values()),
        live_options=ros2 or sapient or any(v is not None for v in live_only),
    )
    if not live:
        _suite(out_dir, quick, **suite)
        return
    request = live_request(
        quick,
        latency_s=latency_s,
        soak_s=soak_s,
        warmup_s=warmup_s,
        turret=turret,
        ptu_baud=ptu_baud,
        scenario=scenario,
        ros2=ros2,
        sapient=sapient,
    )
    _live(out_dir, request, quick)
