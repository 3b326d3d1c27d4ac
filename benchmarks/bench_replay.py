"""Replay speed: ``dronetrack track`` on a 10 Hz Avia recording, as a multiple of real time.

    python benchmarks/bench_replay.py [--seconds 30] [--rounds 3] [--json out.json]

Target (issue 5): at least 20× real time for a 10 Hz Avia stream, on one core.

The recording is the worst case for the reader and the pipeline: an Avia tilted
40° down at open ground, so every pulse returns (24,000 points a frame), on a
turret whose /tf is written at 100 Hz, with a Phantom 4 that descends into view
after the background scan and hovers 2.5 m ahead, and
its ground truth.  It is written in two containers and point formats (ROS 1 with
Livox CustomMsg, ROS 2 MCAP with PointCloud2) and replayed end to end: reading,
decoding, /tf lookup, the pipeline with 5,000 particles, and the ground-truth
bookkeeping.  Each round replays the whole file; the verdict uses the best round.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import json
import math
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from dronetrack.allocator import tune_allocator
from dronetrack.config import BackgroundConfig, CropConfig, PipelineConfig, TrackerConfig
from dronetrack.io.bag_writer import RecordingWriter
from dronetrack.io.recordings import open_recording
from dronetrack.replay import run_replay
from dronetrack.sim.drones import make_drone
from dronetrack.sim.scenario import ScenarioConfig
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.trajectories import Waypoint, fly_waypoints
from dronetrack.sim.turret import make_turret
from dronetrack.sim.world import SimWorld

TARGET_X_REALTIME = 20.0
TARGET = (2.5, 0.0, 0.5)


def write_recording(path: Path, fmt: str, livox: bool, seconds: float) -> int:
    """Record ``seconds`` of the worst-case stream; return the frame count."""
    turret = make_turret("widowx")
    world = SimWorld(
        make_sensor("avia"),
        make_scene("empty"),
        make_drone("phantom4"),
        # Out of view (high above) during the 1 s background scan, then down to hover.
        fly_waypoints((2.5, 0.0, 20.0), [Waypoint(TARGET, 10.0, 10.0)], hold=1.0),
        turret,
        turret.mount,
        0.0,
        np.random.default_rng(0),
        pan=0.0,
        tilt=math.radians(40.0),
    )
    writer = RecordingWriter(path, fmt, turret.mount, livox_custom=livox)  # type: ignore[arg-type]
    n = round(seconds / 0.1)
    for _ in range(n):
        frame, truth = world.step()
        writer.frame(frame, truth.target_position, truth.target_attitude)
    writer.close()
    return n


def replay_config() -> ScenarioConfig:
    pipeline = PipelineConfig(
        crop=CropConfig(min_m=(-200.0, -200.0, -5.0), max_m=(300.0, 200.0, 100.0)),
        background=BackgroundConfig(resolution_m=0.2, lookup_depth=0, scan_s=1.0),
        tracker=TrackerConfig(
            particles=5000,
            cylinder_center_m=TARGET,
            cylinder_radius_m=2.0,
            cylinder_height_m=2.0,
        ),
    )
    return ScenarioConfig(name="bench-replay", pipeline=pipeline)


def time_replay(path: Path) -> tuple[float, float, int]:
    """Wall time [s] of a whole replay, the seconds replayed, and the frames."""
    rec = open_recording(path)
    start = time.perf_counter()
    result = run_replay(rec, replay_config())
    wall = time.perf_counter() - start
    assert result.has_truth
    log = result.run.log.arrays()
    assert log["tracked"][-10:].all(), "the hovering target must be tracked"
    return wall, result.run.simulated_s, len(log["t"]) + 10


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    tune_allocator()
    print(f"Python {platform.python_version()}, numpy {np.__version__}, one thread")
    results: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for fmt, livox, name in (("ros1", True, "avia.bag"), ("ros2-mcap", False, "avia.mcap")):
            path = Path(tmp) / name
            write_recording(path, fmt, livox, args.seconds)
            size_mb = path.stat().st_size / 1e6
            time_replay(path)  # load the numba kernels once
            rounds = []
            for _ in range(args.rounds):
                wall, seconds, frames = time_replay(path)
                rounds.append(seconds / wall)
                print(
                    f"{fmt:>9} {'CustomMsg' if livox else 'PointCloud2':>11}: {frames} frames "
                    f"({size_mb:.0f} MB) in {wall:.2f} s = {1e3 * wall / frames:.2f} ms/frame, "
                    f"{seconds / wall:.1f}× real time"
                )
            best = max(rounds)
            verdict = "meets" if best >= TARGET_X_REALTIME else "MISSES"
            print(f"  best {best:.1f}× real time: {verdict} the target ≥ {TARGET_X_REALTIME:.0f}×")
            results[f"{fmt}-{'livox' if livox else 'pointcloud2'}"] = {
                "x_realtime": rounds,
                "best": best,
                "size_mb": size_mb,
            }
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
