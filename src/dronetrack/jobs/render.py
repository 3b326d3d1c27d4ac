"""Render a scenario: run the simulator with the turret following the truth or held fixed.

This is the simulator's own preview, without any tracking: ``dronetrack render``.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from dronetrack.config.run import ScenarioConfig, dump_scenario
from dronetrack.control.aiming import aim_angles
from dronetrack.pipeline import run
from dronetrack.seams import Sink
from dronetrack.sim.build import build_world, resolve_scenario
from dronetrack.sim.rig import SimSource, TruthAimer
from dronetrack.sim.scene import Scene
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import Frame, Sample, StepResult

__all__ = ["Rendering", "render_scenario", "write_rendering"]

TurretMode = Literal["truth", "fixed"]


@dataclass(frozen=True, slots=True)
class Rendering:
    """Frames and ground truth of a simulated run."""

    config: ScenarioConfig
    scene: Scene
    frames: list[Frame]
    truths: list[FrameTruth]


def render_scenario(
    config: ScenarioConfig,
    turret: TurretMode = "truth",
    progress: Callable[[int, int], None] | None = None,
) -> Rendering:
    """Simulate the scenario's duration.  ``turret="truth"`` keeps the true target centred."""
    config = resolve_scenario(config)
    world: SimWorld = build_world(config)
    # Whole frames covering the duration (a partial last frame counts as one).
    n_frames = max(1, math.ceil(config.duration_s / config.sensor.integration_time_s - 1e-9))
    frames = FrameCollector()
    sinks: list[Sink] = [frames]
    if turret == "truth":
        world.place_turret(*aim_angles(world.target_position(0.0), world.mount))
        # before each next frame, the goal is the target where that frame starts
        sinks.insert(0, TruthAimer(world, latency_s=0.0))
    run(SimSource(world, n_frames), NoTracking(), None, sinks, progress=progress, total=n_frames)
    return Rendering(config, world.lidar.scene, frames.frames, frames.truths)


class NoTracking:
    """The stage of a rendering: every frame passes untouched, as a tracking frame with no
    estimate (so a truth aimer follows the target from the first frame)."""

    def step(self, frame: Frame) -> StepResult:
        return StepResult(frame.end, "track", None, 0, len(frame), None, 0.0)


class FrameCollector:
    """Keeps every frame and its truth."""

    def __init__(self) -> None:
        self.frames: list[Frame] = []
        self.truths: list[FrameTruth] = []

    def write(self, sample: Sample, result: StepResult) -> None:
        assert isinstance(sample.truth, FrameTruth)
        self.frames.append(sample.frame)
        self.truths.append(sample.truth)


FRAME_COLUMNS = (
    "frame",
    "t_start",
    "t_end",
    "n_points",
    "n_target_points",
    "target_x",
    "target_y",
    "target_z",
    "target_vx",
    "target_vy",
    "target_vz",
    "range_m",
    "pan_rad",
    "tilt_rad",
)


def _objects(truths: list[FrameTruth]) -> dict[str, Any]:
    """Every drone and bird (``types.ObjectTruth``): per point ``object_index``, per
    object ``object_ids`` and ``object_kinds``, per frame and object ``object_positions``,
    ``object_velocities`` (NaN while absent) and ``object_present``."""
    objects = [tr.objects for tr in truths if tr.objects is not None]
    if not objects or len(objects) != len(truths):
        return {}
    return {
        "object_index": np.concatenate([o.object_index for o in objects]),
        "object_ids": objects[0].ids,
        "object_kinds": objects[0].kinds,
        "object_positions": np.stack([o.positions for o in objects]),
        "object_velocities": np.stack([o.velocities for o in objects]),
        "object_present": np.stack([o.present for o in objects]),
    }


def write_rendering(rendering: Rendering, out_dir: Path) -> list[Path]:
    """Write frames.npz, frames.csv, scenario.toml and preview.png; return the paths."""
    from dronetrack.sim.preview import plot_preview

    out_dir.mkdir(parents=True, exist_ok=True)
    frames, truths = rendering.frames, rendering.truths
    counts = np.array([len(f) for f in frames])
    world = [f.world_points() for f in frames]
    npz = out_dir / "frames.npz"
    clutter: dict[str, Any] = {}
    if truths and all(tr.clutter is not None for tr in truths):
        # Per point what clutter it is (sim.clutter's codes), per frame the birds.
        clutter["clutter"] = np.concatenate([tr.clutter for tr in truths if tr.clutter is not None])
        birds = [tr.bird_positions for tr in truths if tr.bird_positions is not None]
        clutter["bird_positions"] = np.stack(birds)
    np.savez_compressed(
        npz,
        **clutter,
        **_objects(truths),
        x=np.concatenate([f.points[:, 0] for f in frames]),
        y=np.concatenate([f.points[:, 1] for f in frames]),
        z=np.concatenate([f.points[:, 2] for f in frames]),
        t=np.concatenate([f.t for f in frames]),
        line=np.concatenate([f.line for f in frames]),
        intensity=np.concatenate([f.intensity for f in frames]),
        hit_target=np.concatenate([tr.hit_target for tr in truths]),
        frame=np.repeat(np.arange(len(frames)), counts),
        world=np.concatenate(world),
        frame_start=np.array([f.stamp for f in frames]),
        frame_end=np.array([f.end for f in frames]),
        pose_t=np.stack([f.pose_t for f in frames]),
        poses=np.stack([f.poses for f in frames]),
        target_position=np.stack([tr.target_position for tr in truths]),
        target_velocity=np.stack([tr.target_velocity for tr in truths]),
        target_attitude=np.stack([tr.target_attitude for tr in truths]),
    )
    table = out_dir / "frames.csv"
    with table.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(FRAME_COLUMNS)
        for i, (f, tr) in enumerate(zip(frames, truths, strict=True)):
            sensor_origin = f.poses[-1, :3, 3]
            rng_m = float(np.linalg.norm(tr.target_position - sensor_origin))
            writer.writerow(
                [
                    i,
                    f"{f.stamp:.6f}",
                    f"{f.end:.6f}",
                    len(f),
                    tr.n_target_points,
                    *(f"{v:.4f}" for v in tr.target_position),
                    *(f"{v:.4f}" for v in tr.target_velocity),
                    f"{rng_m:.3f}",
                    f"{tr.turret.pan:.6f}",
                    f"{tr.turret.tilt:.6f}",
                ]
            )
    toml = out_dir / "scenario.toml"
    toml.write_text(dump_scenario(rendering.config))
    png = out_dir / "preview.png"
    plot_preview(rendering.scene, frames, truths, world, png, title=rendering.config.name)
    return [npz, table, toml, png]
