"""The live chain on one machine: latency at the Avia's full point rate, and a memory soak.

    python benchmarks/bench_live.py [--latency-s 20] [--soak-s 600] [--warmup-s 60]
        [--sample-s 5] [--no-turret] [--json out.json]

Targets (issue 14): latency p99 ≤ 20 ms from a frame's last firing to its turret
command; over a 10-minute soak, resident memory flat after warm-up (growth ≤ 5 %),
no packet lost, no frame dropped.

``dronetrack emulate default`` runs in its own process (the Avia at 240,000 points/s on
UDP, two XM430 servos on a pseudo-terminal) and ``live`` runs here against it, with the
Dynamixel turret (``--no-turret``: none).  Threads are not pinned: this is how
``dronetrack live`` runs.  The measuring is ``dronetrack.experiments.bench``'s
(``live_latency``, ``live_soak``), which ``dronetrack bench --live`` runs too.
"""

from __future__ import annotations

import argparse
import json
import platform
from collections.abc import Callable
from pathlib import Path

from dronetrack.allocator import tune_allocator
from dronetrack.experiments.bench import (
    LATENCY_P99_TARGET_MS,
    RSS_GROWTH_TARGET_PCT,
    live_latency,
    live_soak,
)


def _progress(what: str) -> Callable[[float, float], None]:
    def report(done: float, total: float) -> None:
        print(f"\r{what}: {done:5.0f} / {total:.0f} s", end="", flush=True)

    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--latency-s", type=float, default=20.0)
    parser.add_argument("--soak-s", type=float, default=600.0, help="0: no soak")
    parser.add_argument("--warmup-s", type=float, default=60.0)
    parser.add_argument("--sample-s", type=float, default=5.0)
    parser.add_argument("--no-turret", action="store_true")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    tune_allocator()
    turret = not args.no_turret
    print(f"Python {platform.python_version()}; turret: {'Dynamixel' if turret else 'none'}")
    results: dict[str, object] = {}
    lat = live_latency(args.latency_s, turret=turret, progress=_progress("latency"))
    print()
    verdict = "meets" if lat["met"] else "MISSES"
    print(
        f"latency over {args.latency_s:g} s of flight: p50 {lat['latency_ms_p50']:.1f} ms, "
        f"p99 {lat['latency_ms_p99']:.1f} ms ({verdict} p99 ≤ {LATENCY_P99_TARGET_MS:g} ms); "
        f"{lat['frames']} frames, {lat['frames_dropped']} dropped, "
        f"{lat['packets_lost']} packets lost, {lat['turret_reads_missed']} turret reads missed"
    )
    results["live_latency"] = lat
    if args.soak_s > 0:
        soak = live_soak(
            args.soak_s,
            warmup_s=args.warmup_s,
            sample_s=args.sample_s,
            turret=turret,
            progress=_progress("soak"),
        )
        print()
        verdict = "meets" if soak["met"] else "MISSES"
        print(
            f"soak of {args.soak_s:g} s: RSS {soak['rss_mb_warm']:.1f} MB after the "
            f"{args.warmup_s:g} s warm-up, at most {soak['rss_mb_max']:.1f} MB after, "
            f"{soak['rss_mb_end']:.1f} MB at the end: growth {soak['rss_growth_pct']:.2f} % "
            f"({verdict} ≤ {RSS_GROWTH_TARGET_PCT:g} %, no packet lost, no frame dropped); "
            f"{soak['packets_lost']} packets lost, {soak['frames_dropped']} frames dropped, "
            f"latency p50 {soak['latency_ms_p50']:.1f} ms, p99 {soak['latency_ms_p99']:.1f} ms"
        )
        results["live_soak"] = soak
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
