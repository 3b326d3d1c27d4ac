"""Every object's truth, frame by frame, and the figures scored against it: each drone's
own figures (as the single-target metrics score drone 0) and the multi-object figures
of ``motmetrics`` (MOTA, MOTP, IDF1, identity switches).

Multi-object scoring (CLEAR MOT and the identity metrics, Bernardin & Stiefelhagen
2008, Ristani et al. 2016) is ``motmetrics``'s: each frame, the drones that return
points are the ground truth and the tracks in the sensor's view that the tracker holds
possible drones are the hypotheses: those classed drone, and those not classed static
or bird whose p_drone is at least ``HYPOTHESIS_MIN_P``, the classes' own bound below
which a track has evidence against it (``classify.rules.ClassRules.bird_p``: on the
ground, part of a structure, beyond the drone's reach, a steady flight watched for
over 6 s; a static or bird class is the same claim).  A track out of view, one the
turret turned away from, is the tracker's memory of an object no frame can confirm or
deny, as a drone out of view is no truth;
a pair may match within the correct radius, on the 3-D Euclidean distance.  MOTP is
the mean distance of the matched pairs [m].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.classify.rules import ClassRules
from dronetrack.errors import MissingExtraError
from dronetrack.eval.metrics import (
    acquisition_metrics,
    locked_on,
    revisit_max_s,
    scored_tracking,
)
from dronetrack.eval.tracks import TracksLog
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, ObjectTruth

__all__ = [
    "HYPOTHESIS_MIN_P",
    "NOT_DRONE_CLASSES",
    "ObjectsLog",
    "drone_claims",
    "drone_figures",
    "drone_summary",
    "mot_figures",
]

# The classes by which a track claims to be no drone: not hypotheses of a drone.
NOT_DRONE_CLASSES = (TRACK_CLASSES.index("static"), TRACK_CLASSES.index("bird"))
_DRONE = TRACK_CLASSES.index("drone")
# Below this p_drone a track of no class has evidence against being a drone.
HYPOTHESIS_MIN_P = ClassRules().bird_p


class ObjectsLog:
    """The truth of every object, one entry per tracking frame (the same objects in the
    same order every frame: ``ObjectTruth``)."""

    def __init__(self) -> None:
        self.ids: NDArray[np.int64] | None = None
        self.kinds: NDArray[np.str_] | None = None
        self._t: list[float] = []
        self._positions: list[FloatArray] = []
        self._returns: list[NDArray[np.int64]] = []
        self._ranges: list[FloatArray] = []

    def __len__(self) -> int:
        return len(self._t)

    def append(self, t: float, objects: ObjectTruth, sensor: FloatArray) -> None:
        """The objects at the end of the frame ending at ``t``; ``sensor`` (3,) its
        position."""
        if self.ids is None:
            self.ids, self.kinds = objects.ids.copy(), objects.kinds.copy()
        self._t.append(t)
        positions = np.where(objects.present[:, None], objects.positions, np.nan)
        self._positions.append(positions)
        self._returns.append(objects.returns())
        self._ranges.append(np.linalg.norm(positions - sensor, axis=1))

    @property
    def t(self) -> FloatArray:
        return np.asarray(self._t, dtype=np.float64)

    @property
    def positions(self) -> FloatArray:
        """(frames, K, 3), NaN where an object is not present."""
        return np.stack(self._positions) if self._positions else np.empty((0, 0, 3))

    @property
    def returns(self) -> NDArray[np.int64]:
        """(frames, K) returns from each object."""
        return np.stack(self._returns) if self._returns else np.empty((0, 0), np.int64)

    @property
    def ranges(self) -> FloatArray:
        """(frames, K) each object's range from the sensor [m]."""
        return np.stack(self._ranges) if self._ranges else np.empty((0, 0))

    def drones(self) -> NDArray[np.intp]:
        """The indices of the drones among the objects."""
        if self.kinds is None:
            return np.empty(0, dtype=np.intp)
        return np.flatnonzero(self.kinds == "drone")


def drone_figures(
    objects: ObjectsLog,
    t: FloatArray,
    est: FloatArray,
    tracked: NDArray[np.bool_],
    radius: float,
    in_field: list[NDArray[np.bool_] | None] | None = None,
    reach_m: float | None = None,
) -> list[dict[str, Any]]:
    """Each drone's own figures, as ``TrackLog.summary`` scores drone 0 against the
    turret's estimate ``est`` (frames, 3) and its lock ``tracked``: ``coverage_pct``,
    ``max_tracking_distance_m``, ``acquire_s``, ``lock_on_visible_pct`` and the rest of
    ``acquisition_metrics``, its ``visible_frames`` and ``revisit_max_s``
    (``eval.metrics``: its longest wait for the turret while in the field and within
    reach).  ``in_field``: per drone, its
    frames inside the detection area (None: all); ``reach_m``: the sensor's reach for
    the drone [m], from which ``acquire_in_reach_s`` counts (None: left out)."""
    if len(objects) != len(t):
        raise ValueError(f"{len(objects)} object truths for {len(t)} frames")
    positions, returns, ranges = objects.positions, objects.returns, objects.ranges
    assert objects.ids is not None
    out = []
    for n, k in enumerate(objects.drones()):
        gt = positions[:, k]
        err = est - gt
        counts = returns[:, k]
        field = None if in_field is None else in_field[n]
        # max_tracking_distance_m counts frames whose update used a measurement of the
        # drone: for drone 0 the measurement's own error; here, whether the drone
        # returned points (the particle filter weighs every foreground point)
        measured = np.where(counts > 0, 0.0, np.nan)
        coverage, distance = scored_tracking(err, ranges[:, k], radius, measured)
        figures = acquisition_metrics(t, err, tracked, counts, radius, field, ranges[:, k], reach_m)
        visible = counts > 0 if field is None else (counts > 0) & field
        # where a look could find it: in the field (if known) and within reach (if known)
        present = np.asarray(np.isfinite(gt).all(axis=1), dtype=bool)
        if field is not None:
            present &= np.asarray(field, dtype=bool)
        if reach_m is not None:
            present &= ranges[:, k] <= reach_m
        row: dict[str, Any] = {
            "id": int(objects.ids[k]),
            "coverage_pct": coverage,
            "max_tracking_distance_m": distance,
            "visible_frames": int(np.count_nonzero(visible)),
        }
        for key in (
            "acquire_s",
            "acquire_in_reach_s",
            "lock_on_visible_pct",
            "reacquire_max_s",
            "losses",
        ):
            if key in figures:
                row[key] = figures[key]
        row["revisit_max_s"] = revisit_max_s(t, locked_on(err, tracked, radius), present)
        out.append(row)
    return out


def _mm() -> Any:
    try:
        import motmetrics
    except ImportError as err:  # a core dependency; a broken install says so
        raise MissingExtraError(
            "multi-object metrics need motmetrics: pip install motmetrics"
        ) from err
    return motmetrics


def drone_claims(rows: NDArray[Any]) -> NDArray[np.bool_]:
    """(M,) which ``TracksLog`` rows the tracker holds possible drones (see the module
    docstring): classed drone, or of no class with p_drone ≥ ``HYPOTHESIS_MIN_P``."""
    cls = rows["cls"]
    maybe = ~np.isin(cls, NOT_DRONE_CLASSES) & (rows["p_drone"] >= HYPOTHESIS_MIN_P)
    out: NDArray[np.bool_] = (cls == _DRONE) | maybe
    return out


def mot_figures(
    objects: ObjectsLog, tracks: TracksLog, radius: float, reach_m: float | None = None
) -> dict[str, Any]:
    """The multi-object figures of the drones (see the module docstring): ``mota``,
    ``motp_m``, ``idf1``, ``id_switches``, ``false_positives``, ``misses``, ``matches``,
    ``frames``, and per drone its identity switches, the share of its visible frames
    its track matched (``own_track_pct``) and the time from its first visible frame to
    the first one a track matched it (``track_acquire_s``: acquired as a track, whether
    or not the turret serves it); given the sensor's reach ``reach_m`` [m], also from
    its first visible frame within reach (``track_acquire_in_reach_s``: a drone flying
    in from beyond reach draws single returns out there, which start no track)."""
    mm = _mm()
    acc = mm.MOTAccumulator(auto_id=True)
    rows = tracks.rows
    frame_of = np.searchsorted(objects.t, rows["t"])
    drones = objects.drones()
    positions, returns = objects.positions, objects.returns
    assert objects.ids is not None
    for f in range(len(objects)):
        seen = drones[returns[f, drones] > 0]
        here = rows[(frame_of == f) & drone_claims(rows) & rows["in_view"]]
        gt = positions[f, seen]
        d = np.linalg.norm(gt[:, None, :] - here["position"][None, :, :], axis=2)
        acc.update(
            objects.ids[seen].tolist(), here["id"].tolist(), np.where(d <= radius, d, np.nan)
        )
    summary = (
        mm.metrics.create()
        .compute(
            acc,
            metrics=[
                "mota",
                "motp",
                "idf1",
                "num_switches",
                "num_false_positives",
                "num_misses",
                "num_matches",
                "num_frames",
            ],
            name="drones",
        )
        .iloc[0]
    )
    events = acc.mot_events
    per: list[dict[str, Any]] = []
    for k in drones:
        mine = events[events["OId"] == objects.ids[k]]
        seen_frames = int(np.count_nonzero(returns[:, k] > 0))
        matched = mine["Type"].isin(["MATCH", "SWITCH"])
        hit = int(matched.sum())
        matched_frames = mine.index.get_level_values(0)[matched]
        per.append(
            {
                "id": int(objects.ids[k]),
                "id_switches": int((mine["Type"] == "SWITCH").sum()),
                "own_track_pct": 100.0 * hit / seen_frames if seen_frames else None,
                "track_ids": int(mine["HId"].dropna().nunique()),
                "track_acquire_s": _first_match_s(objects.t, returns[:, k] > 0, matched_frames),
            }
        )
        if reach_m is not None:
            near = (returns[:, k] > 0) & (objects.ranges[:, k] <= reach_m)
            per[-1]["track_acquire_in_reach_s"] = _first_match_s(objects.t, near, matched_frames)

    def number(value: Any) -> float | None:
        v = float(value)
        return v if np.isfinite(v) else None

    return {
        "objects": "drones",
        "radius_m": radius,
        "mota": number(summary["mota"]),
        "motp_m": number(summary["motp"]),
        "idf1": number(summary["idf1"]),
        "id_switches": int(summary["num_switches"]),
        "false_positives": int(summary["num_false_positives"]),
        "misses": int(summary["num_misses"]),
        "matches": int(summary["num_matches"]),
        "frames": int(summary["num_frames"]),
        "drones": per,
    }


def _first_match_s(t: FloatArray, visible: NDArray[np.bool_], matched_frames: Any) -> float | None:
    """From a drone's first ``visible`` frame to the first frame at or after it that a
    track matched it [s] (motmetrics' frame ids are the frames' indices); None if none
    did."""
    if not visible.any():
        return None
    first = int(np.argmax(visible))
    later = np.asarray(matched_frames, dtype=np.int64)
    later = later[later >= first]
    return float(t[int(later.min())] - t[first]) if len(later) else None


def _over(values: list[Any], worst: Callable[[list[float]], float]) -> tuple[float, float]:
    """(mean, worst) of the numbers among ``values`` (None left out), NaN without any."""
    known = [float(v) for v in values if v is not None]
    if not known:
        return math.nan, math.nan
    return float(np.mean(known)), float(worst(known))


def drone_summary(drones: list[dict[str, Any]]) -> dict[str, float]:
    """A run's per-drone figures (``drones`` of metrics.json: ``drone_figures`` with
    ``mot_figures``' per-drone entries) over its drones: the mean and the worst drone's
    ``coverage_pct``, ``lock_on_visible_pct`` and ``own_track_pct`` (``*_mean_pct``,
    ``*_min_pct``), of ``acquire_s`` (``acquire_mean_s``, ``acquire_max_s``, over the
    drones acquired), of ``acquire_in_reach_s``, ``track_acquire_s`` and
    ``track_acquire_in_reach_s`` (likewise), ``never_acquired`` (drones
    visible but never acquired), ``id_switches_max`` and ``revisit_max_s`` (the worst
    drone's longest wait for the turret); NaN where no drone has the figure."""
    out: dict[str, float] = {}
    for key in ("coverage", "lock_on_visible", "own_track"):
        mean, low = _over([d.get(f"{key}_pct") for d in drones], min)
        out[f"{key}_mean_pct"], out[f"{key}_min_pct"] = mean, low
    out["acquire_mean_s"], out["acquire_max_s"] = _over([d.get("acquire_s") for d in drones], max)
    for key in ("acquire_in_reach", "track_acquire", "track_acquire_in_reach"):
        out[f"{key}_mean_s"], out[f"{key}_max_s"] = _over([d.get(f"{key}_s") for d in drones], max)
    out["never_acquired"] = float(
        sum(d.get("acquire_s") is None and d.get("visible_frames", 0) > 0 for d in drones)
    )
    out["id_switches_max"] = _over([d.get("id_switches") for d in drones], max)[1]
    out["revisit_max_s"] = _over([d.get("revisit_max_s") for d in drones], max)[1]
    return out
