"""How a drone's and a bird's returns compare in the simulator
(``experiments.appearance``): known answers on frames built by hand."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dronetrack.experiments.appearance import SightingLog, appearance_rows, sightings
from dronetrack.types import Frame, ObjectTruth, Sample


def _frame(points: np.ndarray, intensity: np.ndarray) -> Frame:
    n = len(points)
    return Frame(
        stamp=0.0,
        duration=0.1,
        points=np.asarray(points, dtype=np.float64),
        t=np.zeros(n),
        line=np.zeros(n, dtype=np.uint8),
        intensity=np.asarray(intensity, dtype=np.float32),
        pose_t=np.zeros(1),
        poses=np.eye(4)[None],
    )


def _truth(kinds: list[str], object_index: list[int]) -> ObjectTruth:
    k = len(kinds)
    return ObjectTruth(
        ids=np.arange(k),
        kinds=np.array(kinds),
        positions=np.zeros((k, 3)),
        velocities=np.zeros((k, 3)),
        present=np.ones(k, dtype=bool),
        object_index=np.array(object_index),
    )


def test_each_object_hit_gives_its_range_angle_off_axis_returns_and_intensity() -> None:
    # a drone's three returns 50 m along the axis, a bird's one return 30 m out at 10°
    # off it, a return of the scene; an object of no return gives no row
    off = math.radians(10.0)
    points = np.array(
        [
            [50.0, 0.0, 0.1],
            [50.0, 0.1, -0.1],
            [50.0, -0.1, 0.0],
            [30.0 * math.cos(off), 30.0 * math.sin(off), 0.0],
            [80.0, 5.0, 0.0],
        ]
    )
    frame = _frame(points, np.array([10.0, 20.0, 30.0, 45.0, 99.0]))
    seen = sightings(frame, _truth(["drone", "bird", "bird"], [0, 0, 0, 1, -1]))
    assert seen.kind.tolist() == ["drone", "bird"]
    assert seen.returns.tolist() == [3, 1]
    assert seen.intensity == pytest.approx([20.0, 45.0])
    assert seen.range_m[1] == pytest.approx(30.0)
    assert seen.range_m[0] == pytest.approx(np.hypot(50.0, 0.1))  # the median of the three
    assert seen.off_axis_rad[0] == pytest.approx(0.0, abs=1e-12)
    assert seen.off_axis_rad[1] == pytest.approx(off)


def test_rows_hold_each_band_the_quantiles_of_its_sightings() -> None:
    log = SightingLog()
    rng = np.random.default_rng(3)
    for n in range(1, 11):  # a drone 20 m out with n returns, n = 1..10
        pts = np.column_stack([np.full(n, 20.0), rng.normal(0, 0.05, (n, 2))])
        frame = _frame(pts, np.full(n, 12.0))
        truth = SimpleNamespace(objects=_truth(["drone"], [0] * n))
        log.write(Sample(frame, truth=truth), None)  # type: ignore[arg-type]
        log.write(Sample(frame), None)  # type: ignore[arg-type]  # no truth: passed over
    assert len(log.parts) == 10
    rows = appearance_rows(log.all, kinds=("drone", "bird"))
    assert len(rows) == 1  # no bird
    kind, r_lo, r_hi, o_lo, o_hi, frames, ret, inten = rows[0]
    assert (kind, r_lo, r_hi, o_lo, o_hi, frames) == ("drone", 10.0, 40.0, 0.0, 5.0, 10)
    assert ret == pytest.approx(np.percentile(np.arange(1, 11), [10, 50, 90]))
    assert inten == pytest.approx([12.0, 12.0, 12.0])
    assert appearance_rows(log.all, min_frames=11) == []
