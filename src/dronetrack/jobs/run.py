"""What every job shares, simulator or not: the resolved configuration, the pipeline a
rig's turret gets, the seeds, a finished run and its output folder.

Nothing here imports the simulator, so ``track`` of a recording never loads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.config.pipeline import crop_box, field_of_regard, scan_area
from dronetrack.config.rig import TurretSpec, narrow_field_of_view, target_spec, turret_spec
from dronetrack.config.run import ScenarioConfig, dump_scenario
from dronetrack.config.tomlfile import tidy_model
from dronetrack.eval.classes import class_figures
from dronetrack.eval.log import TrackLog
from dronetrack.eval.objects import drone_figures, mot_figures
from dronetrack.formats.background import read_background_settings
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import FloatArray
from dronetrack.jobs.background import load_saved
from dronetrack.pipeline import Pipeline
from dronetrack.pipeline.factory import build_pipeline
from dronetrack.pipeline.kernels import KernelWarmUp
from dronetrack.pipeline.trackers import noise_parameters, resolve_tracker
from dronetrack.sinks.run_folder import (
    FramesCsvWriter,
    TracksCsvWriter,
    check_run_dir,
    prepare_run_dir,
)

__all__ = [
    "NO_WARM_UP",
    "RunFolder",
    "RunResult",
    "resolve_pipeline",
    "run_seeds",
    "turret_pipeline",
    "write_run",
]

NO_WARM_UP = KernelWarmUp(0.0, 0)


def resolve_pipeline(cfg: ScenarioConfig) -> ScenarioConfig:
    """The configuration with the pipeline's derived values written out: the drone's
    diagonal and the σ values of eq. (11), and a background file's own settings and
    absolute path."""
    pipeline = cfg.pipeline
    s_diag = target_spec(cfg.drone.model).s_diag
    tracker = resolve_tracker(pipeline.tracker, cfg.sensor.integration_time_s, s_diag)
    background = pipeline.background
    if background.file is not None:
        path = Path(background.file).expanduser().resolve()
        stored = read_background_settings(path)
        background = background.model_copy(
            update={
                "file": str(path),
                "resolution_m": stored.resolution,
                "inflate_voxels": stored.inflate,
                "lookup_depth": stored.lookup_depth,
                "min_hits": stored.min_hits,
                "min_neighbours": stored.min_neighbours,
            }
        )
    # The crop box and the background scan, as set or from the field of regard.
    low, high = crop_box(pipeline, turret_spec(cfg.turret).mount.base)
    crop = pipeline.crop.model_copy(update={"min_m": low, "max_m": high})
    pan, tilt, period = scan_area(pipeline)
    background = background.model_copy(
        update={"scan_pan_deg": pan, "scan_tilt_deg": tilt, "scan_period_s": period}
    )
    pipeline = pipeline.model_copy(
        update={"tracker": tracker, "background": background, "crop": crop}
    )
    # The numbers the run uses are those its config.toml holds, so it re-runs the same.
    return tidy_model(cfg.model_copy(update={"pipeline": pipeline}))


def detection_area(cfg: ScenarioConfig, points: FloatArray) -> NDArray[np.bool_] | None:
    """(N,) True where a point lies where the pipeline can detect it: inside the crop box
    and the field of regard (if set) of a turret on the ground; None on a moving observer
    (its crop box moves with it) and for non-finite points False."""
    if cfg.observer is not None:
        return None
    base = turret_spec(cfg.turret).mount.base
    low, high = crop_box(cfg.pipeline, base)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    with np.errstate(invalid="ignore"):
        inside: NDArray[np.bool_] = np.all((p >= low) & (p <= high), axis=1)
    field = field_of_regard(cfg.pipeline, base)
    if field is not None:
        inside &= field.contains(p)
    return inside


def run_seeds(seed: int) -> tuple[np.random.SeedSequence, np.random.SeedSequence]:
    """The simulator's and the filters' seeds of a run with ``seed``: a replay of a
    recorded run draws its filter from the same one."""
    sim, filters = np.random.SeedSequence(seed).spawn(2)
    return sim, filters


def turret_pipeline(
    cfg: ScenarioConfig, period: float, turret: TurretSpec, rng: np.random.Generator
) -> Pipeline:
    """The pipeline ``cfg`` describes, for frames of ``period`` s from this turret."""
    file = cfg.pipeline.background.file
    return build_pipeline(
        cfg.pipeline,
        period,
        turret.mount,
        (turret.pan.lower, turret.pan.upper),
        (turret.tilt.lower, turret.tilt.upper),
        rng,
        saved=load_saved(Path(file).expanduser()) if file is not None else None,
        field_of_view=narrow_field_of_view(cfg.sensor.model),
    )


def outside_share(inside: NDArray[np.bool_]) -> float:
    """``outside_field_pct``: of the frames from the drone's first one inside the detection
    area on, the share outside it [%] (a drone waiting on the ground below the crop box
    before take-off has not left it); 100 if it never enters (0 without frames)."""
    entered = np.flatnonzero(inside)
    if not len(entered):
        return 100.0 if len(inside) else 0.0
    return 100.0 * float(np.mean(~inside[int(entered[0]) :]))


@dataclass(frozen=True, slots=True)
class RunResult:
    """A finished run: closed-loop, or a replay."""

    config: ScenarioConfig  # resolved
    log: TrackLog
    pipeline: Pipeline
    wall_s: float
    simulated_s: float  # source time the frames covered [s]
    kernels: KernelWarmUp = NO_WARM_UP  # the warm-up before the timed loop
    interrupted: bool = False  # Ctrl-C ended it early: the log holds the frames done

    def object_metrics(self) -> dict[str, Any]:
        """With every object's truth (the simulator's): ``drones``, each drone's own
        figures (as drone 0's in the run's metrics, against the turret's estimate, with
        its identity switches and own-track share), and ``mot``, the multi-object
        figures (``eval.objects``); and ``classes``, the class confusion matrix and the
        static objects' time to class (``eval.classes``); empty otherwise."""
        objects = self.log.objects
        if len(objects) != len(self.log) or len(objects) == 0:
            return {}
        radius = self.config.pipeline.evaluation.correct_radius_m
        classes = class_figures(objects, self.log.tracks, radius)
        if len(objects.drones()) == 0:
            return {"classes": classes}
        est = self.log.est
        positions = objects.positions
        fields = [detection_area(self.config, positions[:, k]) for k in objects.drones()]
        reach = self.config.pipeline.evaluation.reach_m
        drones = drone_figures(objects, self.log.t, est, self.log.tracked, radius, fields, reach)
        mot = mot_figures(objects, self.log.tracks, radius, reach)
        for own, scored in zip(drones, mot.pop("drones"), strict=True):
            own.update(scored)
        return {"drones": drones, "mot": mot, "classes": classes}

    @property
    def realtime_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else math.inf

    def metrics(self, objects: dict[str, Any] | None = None) -> dict[str, Any]:
        """metrics.json's figures; ``objects``: ``object_metrics()`` if already computed."""
        evaluation = self.config.pipeline.evaluation
        gt = self.log.gt
        known = np.all(np.isfinite(gt), axis=1)
        area = detection_area(self.config, gt) if known.any() else None
        out = self.log.summary(
            evaluation.correct_radius_m, evaluation.min_consecutive, area, evaluation.reach_m
        )
        if area is not None:
            out["outside_field_pct"] = outside_share(area[known])
        out.update(self.object_metrics() if objects is None else objects)
        out["realtime_factor"] = self.realtime_factor
        out["wall_s"] = self.wall_s
        if self.interrupted:
            out["interrupted"] = True
        return out


class RunFolder:
    """A run's output folder, written as the run goes: ``frames.csv`` row by row from
    the first tracking frame, and tracks.csv with it (flushed, so an interrupted or
    crashed run keeps its frames), then at the end config.toml, metrics.json, the
    plots and the scanned background.  The folder is checked at once and created at
    the first row, so a run refused before it tracks anything leaves nothing behind.

    ``log_sink`` is the ``on_row`` of the run's ``TrackLogSink``: it streams frames.csv
    and tracks.csv.
    """

    def __init__(
        self,
        out_dir: Path,
        site: SiteFrame | None = None,
        base: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        """``site``: the world frame on the Earth, for tracks.csv's WGS-84 columns;
        ``base``: the turret base in the world frame, whence its ranges."""
        self.out_dir = check_run_dir(out_dir)
        self.site = site
        self.base = base
        self._frames: FramesCsvWriter | None = None
        self._tracks: TracksCsvWriter | None = None

    def log_sink(self, log: TrackLog) -> None:
        if self._frames is None or self._tracks is None:
            folder = prepare_run_dir(self.out_dir)
            self._frames = FramesCsvWriter(folder / "frames.csv")
            self._tracks = TracksCsvWriter(folder / "tracks.csv", self.site, self.base)
        self._frames.write(log)
        self._tracks.write(log.tracks)

    def close(self) -> None:
        if self._frames is not None:
            self._frames.close()
        if self._tracks is not None:
            self._tracks.close()

    def finish(self, run: RunResult, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Write the rest of the run (see ``write_run``); return its metrics."""
        from dronetrack.jobs.background import save_model
        from dronetrack.sinks.run_folder import write_metrics, write_plots

        self.log_sink(run.log)
        self.close()
        out_dir = self.out_dir
        background = run.pipeline.background
        learning = run.pipeline.learning
        config = run.config
        scanned = background is not None and background.ready
        if learning is not None and len(learning):
            # the map learnt: save what it holds now, on top of the scanned or loaded one
            save_model(background if scanned else None, out_dir / "background.npz", learning)
        elif scanned and config.pipeline.background.file is None:
            save_model(background, out_dir / "background.npz")
        (out_dir / "config.toml").write_text(dump_scenario(config))
        metrics = run.metrics() if extra is None else extra
        write_metrics(metrics, out_dir / "metrics.json")
        noise = noise_parameters(config.pipeline.tracker, config.sensor.integration_time_s)
        radius = config.pipeline.evaluation.correct_radius_m
        write_plots(
            run.log, out_dir, noise.threshold, config.name, radius, config.pipeline.tracker.kind
        )
        return metrics


def write_run(run: RunResult, out_dir: Path, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """Write config.toml, frames.csv, metrics.json, the plots and the scanned background
    (``background.npz``, to load with ``[pipeline.background] file``); return the metrics
    (``extra`` replaces the run's own)."""
    return RunFolder(out_dir).finish(run, extra)
