"""How often a drone hovering on the sensor's axis returns a point, by range: the
share of frames P(r) the classify stage's test of a track that returns too often
weighs a track against (``classify.return_share``; ``config.reach.RETURN_SHARE``).

The drone hovers still on the sensor's x axis, r ahead of the turret and 20 m up, and
the turret follows it (``turret_mode`` truth), so it stays where the scan pattern is
densest; each range is flown for ``duration`` seconds per seed, over seeds other than
the test scenarios' 0-9.  The classes weigh a track by its range from the sensor, so
each share is put at the drone's mean range from the sensor over its frames (the
ObjectsLog's, √(r² + Δz²) with Δz the drone's height above the sensor), not at r.
The logistic

    P(r) = 1 / (1 + exp((r − r₅₀) / s))

is fitted to the shares by weighted least squares (each share's binomial σ,
√(P(1 − P) / n), at least that of one frame in the range's n).

``python -m dronetrack.experiments.return_share [--sensor avia] [--drone phantom4]
[--seeds 10,11] [--ranges 100,110,...] [--duration 40]`` prints each range's share
and the fit.
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.optimize import curve_fit

from dronetrack.classify.return_share import return_share
from dronetrack.errors import DronetrackError, InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = ["fit_return_share", "frame_share", "measure"]

SEEDS = (10, 11)
RANGES_M = (100, 110, 120, 125, 130, 135, 140, 145, 150, 155, 160, 165, 170, 175, 180, 190, 200)
HEIGHT_M = 20.0
DURATION_S = 40.0


def frame_share(
    range_m: float, seed: int, *, sensor: str, drone: str, duration_s: float = DURATION_S
) -> tuple[float, int, float]:
    """The share of tracking frames in which the drone, hovering ``range_m`` ahead of
    the turret on the sensor's axis, returned a point, the frames counted and the
    drone's mean range from the sensor over them [m]."""
    from dronetrack.config.run import apply_overrides
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "hover.csv"
        times = np.arange(0.0, 1000.0, 10.0)
        path.write_text(
            "t,x,y,z\n" + "".join(f"{t},{range_m},0,{HEIGHT_M}\n" for t in times),
            encoding="utf-8",
        )
        cfg = apply_overrides(
            get_scenario("default"),
            seed=seed,
            trajectory=path,
            duration=duration_s,
            turret_mode="truth",
            sensor=sensor,
            drone=drone,
        )
        run = run_simulation(cfg)
    objects = run.log.objects
    drone_index = objects.drones()[0]
    returns = objects.returns[:, drone_index]
    return float(np.mean(returns > 0)), len(returns), float(np.mean(objects.ranges[:, drone_index]))


def fit_return_share(
    ranges_m: Sequence[float], shares: Sequence[float], frames: Sequence[int]
) -> tuple[float, float]:
    """(r₅₀, s) [m] of the logistic fitted to the shares (see the module docstring)."""
    r = np.asarray(ranges_m, dtype=np.float64)
    p = np.asarray(shares, dtype=np.float64)
    n = np.asarray(frames, dtype=np.float64)
    if len(r) < 3 or not ((p > 0.5).any() and (p < 0.5).any()):
        raise InputError("the shares must span 1/2 over three ranges or more to fit r50 and s")
    floor = 1.0 / n
    sigma = np.sqrt(np.maximum(p * (1.0 - p), floor * (1.0 - floor)) / n)
    r50_guess = float(np.interp(0.5, p[::-1], r[::-1]))

    def model(x: FloatArray, r50: float, s: float) -> FloatArray:
        return return_share(x, r50, s)

    (r50, s), _ = curve_fit(model, r, p, p0=(r50_guess, 10.0), sigma=sigma)
    return float(r50), float(abs(s))


def measure(
    ranges_m: Sequence[float],
    seeds: Sequence[int],
    *,
    sensor: str,
    drone: str,
    duration_s: float = DURATION_S,
) -> tuple[list[float], list[int], list[float]]:
    """Each range's share over the seeds (their frames pooled), its frames and the
    drone's mean range from the sensor over them [m] (the range to fit against)."""
    shares, frames, distances = [], [], []
    for r in ranges_m:
        runs = [frame_share(r, s, sensor=sensor, drone=drone, duration_s=duration_s) for s in seeds]
        n = sum(k for _, k, _ in runs)
        shares.append(sum(share * k for share, k, _ in runs) / n)
        frames.append(n)
        distances.append(sum(d * k for _, k, d in runs) / n)
    return shares, frames, distances


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dronetrack.experiments.return_share")
    parser.add_argument("--sensor", default="avia")
    parser.add_argument("--drone", default="phantom4")
    parser.add_argument("--seeds", default=",".join(map(str, SEEDS)))
    parser.add_argument("--ranges", default=",".join(map(str, RANGES_M)))
    parser.add_argument("--duration", type=float, default=DURATION_S)
    args = parser.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
        ranges = [float(r) for r in args.ranges.split(",")]
    except ValueError:
        parser.error("--seeds and --ranges take comma-separated numbers")
    try:
        shares, frames, distances = measure(
            ranges, seeds, sensor=args.sensor, drone=args.drone, duration_s=args.duration
        )
        r50, s = fit_return_share(distances, shares, frames)
    except DronetrackError as exc:
        print(f"error: {exc}")
        return 2
    print(f"{args.drone} on the {args.sensor}'s axis, seeds {args.seeds}")
    print("ahead_m  range_m  share  frames  fit")
    for r, d, p, n in zip(ranges, distances, shares, frames, strict=True):
        fit = float(return_share(np.array(d), r50, s))
        print(f"{r:7.0f}  {d:7.1f}  {p:5.3f}  {n:6d}  {fit:5.3f}")
    print(f"r50 = {r50:.1f} m, s = {s:.2f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
