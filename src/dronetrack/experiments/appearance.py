"""How a drone's and a bird's returns compare in the simulator: how many returns each
gives a frame and how bright they are (the Livox reflectivity encoding), by range and
by the angle off the sensor's axis, where the scan pattern's density differs.

The classify stage (``classify.rules``) weighs neither (see docs/pipeline.md,
Classes).  This measures why: in the simulator the intensity would tell a drone from
a bird in every frame, and the count near the sensor, for reasons a real site does
not give.

- Every bird has one reflectivity (``[scene.clutter] bird_reflectivity``, 0.3 diffuse),
  so every bird return has one intensity, while a drone's shell, arms and propellers
  give a spread.  Real birds range from a crow's black to a gull's white.
- The simulator's birds are 0.2-0.5 m across (``bird_size_m``) and 0.1 L thick, so
  within 70 m they return fewer points than a Phantom 4 in the same part of the
  pattern (beyond, as many).  Pigeons, crows and gulls span 0.6-1.5 m, as large as a
  drone or larger.

``python -m dronetrack.experiments.appearance [SCENARIO] [--seeds 10,11,...]`` flies
the scenario (``outdoor-clutter`` by default: the default flight amid five birds)
over seeds other than the test scenarios' 0-9 and prints, per kind, range band and
off-axis band, the 10th, 50th and 90th percentiles of each object's returns a frame
and of their mean intensity, over the frames where it gave any.
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DronetrackError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame, ObjectTruth, Sample, StepResult, truth_objects

__all__ = ["SightingLog", "Sightings", "appearance_rows", "sightings"]

RANGE_EDGES_M = (10.0, 40.0, 70.0, 100.0, 140.0)
OFF_AXIS_EDGES_DEG = (0.0, 5.0, 10.0, 20.0, 40.0)
QUANTILES = (10.0, 50.0, 90.0)


@dataclass(frozen=True, slots=True)
class Sightings:
    """One row per object per frame in which it gave returns (M,)."""

    kind: NDArray[np.str_]
    range_m: FloatArray  # the median range of its returns [m]
    off_axis_rad: FloatArray  # the angle of its returns' centroid off the sensor's x axis
    returns: NDArray[np.int64]
    intensity: FloatArray  # the mean intensity of its returns (Livox encoding)

    @staticmethod
    def concat(parts: Sequence[Sightings]) -> Sightings:
        if not parts:
            return Sightings(
                np.empty(0, np.str_),
                np.empty(0),
                np.empty(0),
                np.empty(0, np.int64),
                np.empty(0),
            )
        return Sightings(
            np.concatenate([p.kind for p in parts]),
            np.concatenate([p.range_m for p in parts]),
            np.concatenate([p.off_axis_rad for p in parts]),
            np.concatenate([p.returns for p in parts]),
            np.concatenate([p.intensity for p in parts]),
        )


def sightings(frame: Frame, objects: ObjectTruth) -> Sightings:
    """Each object that gave the frame returns, as ``Sightings`` (its points are in
    the sensor frame, x along the sensor's axis)."""
    index = objects.object_index
    hit = np.unique(index[index >= 0])
    rows = []
    for k in hit.tolist():
        mine = index == k
        pts = frame.points[mine]
        c = pts.mean(axis=0)
        # θ_off = arccos(c_x / |c|)
        off = float(np.arccos(np.clip(c[0] / max(float(np.linalg.norm(c)), 1e-12), -1.0, 1.0)))
        rows.append(
            (
                float(np.median(np.linalg.norm(pts, axis=1))),
                off,
                int(mine.sum()),
                float(np.mean(frame.intensity[mine])),
            )
        )
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    return Sightings(
        objects.kinds[hit].astype(np.str_),
        table[:, 0],
        table[:, 1],
        table[:, 2].astype(np.int64),
        table[:, 3],
    )


class SightingLog:
    """A sink that keeps every frame's ``sightings`` (frames without truth are passed
    over)."""

    def __init__(self) -> None:
        self.parts: list[Sightings] = []

    def write(self, sample: Sample, result: StepResult) -> None:
        objects = truth_objects(sample.truth)
        if objects is not None and len(objects):
            self.parts.append(sightings(sample.frame, objects))

    def close(self) -> None:
        pass

    @property
    def all(self) -> Sightings:
        return Sightings.concat(self.parts)


def appearance_rows(
    seen: Sightings,
    kinds: Sequence[str] = ("drone", "bird"),
    range_edges: Sequence[float] = RANGE_EDGES_M,
    off_axis_edges_deg: Sequence[float] = OFF_AXIS_EDGES_DEG,
    min_frames: int = 5,
) -> list[tuple[str, float, float, float, float, int, FloatArray, FloatArray]]:
    """Per kind, range band [lo, hi) and off-axis band [lo, hi) with at least
    ``min_frames`` sightings: (kind, r_lo, r_hi, off_lo, off_hi [deg], frames, the
    ``QUANTILES`` of its returns, and of its mean intensity)."""
    off_deg = np.degrees(seen.off_axis_rad)
    out = []
    for kind in kinds:
        for r_lo, r_hi in itertools.pairwise(range_edges):
            for o_lo, o_hi in itertools.pairwise(off_axis_edges_deg):
                m = (
                    (seen.kind == kind)
                    & (seen.range_m >= r_lo)
                    & (seen.range_m < r_hi)
                    & (off_deg >= o_lo)
                    & (off_deg < o_hi)
                )
                n = int(m.sum())
                if n < min_frames:
                    continue
                out.append(
                    (
                        kind,
                        r_lo,
                        r_hi,
                        o_lo,
                        o_hi,
                        n,
                        np.percentile(seen.returns[m], QUANTILES),
                        np.percentile(seen.intensity[m], QUANTILES),
                    )
                )
    return out


def main(argv: Sequence[str] | None = None) -> None:
    from dronetrack.config.run import apply_overrides
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    parser = argparse.ArgumentParser(prog="python -m dronetrack.experiments.appearance")
    parser.add_argument("scenario", nargs="?", default="outdoor-clutter", help="a name or a .toml")
    parser.add_argument("--seeds", default="10,11,12,13,14")
    args = parser.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds: a comma-separated list of integers, got {args.seeds!r}")
    log = SightingLog()
    try:
        base = get_scenario(str(args.scenario))  # a name or a .toml file
        for seed in seeds:
            run_simulation(apply_overrides(base, seed=seed), sinks=[log])
    except DronetrackError as err:
        parser.error(str(err))
    print("kind   range [m]  off axis [°]  frames  returns p10/50/90  intensity p10/50/90")
    for kind, r_lo, r_hi, o_lo, o_hi, n, ret, inten in appearance_rows(log.all):
        print(
            f"{kind:6s} {r_lo:4.0f}-{r_hi:<4.0f}  {o_lo:4.0f}-{o_hi:<4.0f}    {n:6d}  "
            f"{ret[0]:4.0f} {ret[1]:4.0f} {ret[2]:4.0f}       "
            f"{inten[0]:5.1f} {inten[1]:5.1f} {inten[2]:5.1f}"
        )


if __name__ == "__main__":
    main()
