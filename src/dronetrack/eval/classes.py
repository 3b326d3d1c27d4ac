"""How well each track's class says what it follows: the class confusion matrix of a run
against every object's truth, and how soon a static object's track is classed static.

A track-frame (one row of ``tracks.csv``) *follows* the truth object nearest to its
position within the correct radius at that frame (objects not present are not there);
one with none within the radius follows ``none``: the static scene, clutter or
nothing.  The matrix counts the track-frames of tracks at least ``min_age_s`` old (the
issue's "after 2 s of track life"; a track's age counts from its first row), by what
they follow (rows: ``CONFUSION_KINDS``) and by their class (columns:
``TRACK_CLASSES``).

A track *holds still on the static world* when every one of its frames follows ``none``
or a ``static`` object, clusters updated it over at least ``seen_s`` (one update at
its birth shows nothing of how its object moves), and its position on those frames
never strays more than ``still_m`` from its first one (a track coasting after it lost
its object drifts on its last velocity, which is no movement of the object).  Its time
to class is from its first row (its birth, on confirmation) to its first row classed
``static``, and the time the turret held one is its locked rows times the frame period.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from dronetrack.eval.objects import ObjectsLog
from dronetrack.eval.tracks import TracksLog
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import OBJECT_KINDS, TRACK_CLASSES

__all__ = [
    "CONFUSION_KINDS",
    "NONE",
    "StaticLives",
    "class_figures",
    "confusion_counts",
    "confusion_figures",
    "followed_kinds",
    "followed_objects",
    "row_percentages",
    "static_figures",
    "static_held_s",
    "static_lives",
    "track_ages",
]

NONE = "none"  # what a track-frame follows when no truth object is within the radius
CONFUSION_KINDS: tuple[str, ...] = (*OBJECT_KINDS, NONE)
_STATIC = TRACK_CLASSES.index("static")
_DRONE = TRACK_CLASSES.index("drone")
# the rounding of a difference of two time stamps [s], far below any frame period
TIME_TOL_S = 1e-6


def followed_objects(
    frame_of: NDArray[np.intp],
    positions: FloatArray,
    truth_positions: FloatArray,
    radius: float,
) -> NDArray[np.intp]:
    """Per track-frame, the index of the truth object it follows: the nearest within
    ``radius`` [m] at its frame, −1 where none is.

    frame_of: (M,) each track-frame's index into the truth frames; positions: (M, 3)
    the tracks' positions; truth_positions: (frames, K, 3), NaN where an object is not
    present.
    """
    m = len(frame_of)
    k = truth_positions.shape[1] if truth_positions.ndim == 3 else 0
    if m == 0 or k == 0:
        return np.full(m, -1, dtype=np.intp)
    d = np.linalg.norm(truth_positions[frame_of] - positions[:, None, :], axis=2)
    d = np.where(np.isfinite(d), d, np.inf)
    nearest = np.argmin(d, axis=1)
    within = d[np.arange(m), nearest] <= radius
    return np.where(within, nearest, -1).astype(np.intp)


def track_ages(t: FloatArray, ids: NDArray[np.int64]) -> FloatArray:
    """(M,) each track-frame's age: its time less the time of its track's first row [s]."""
    if len(t) == 0:
        return np.zeros(0)
    _, inverse = np.unique(ids, return_inverse=True)
    first = np.full(int(inverse.max()) + 1, np.inf)
    np.minimum.at(first, inverse, t)
    return np.asarray(t - first[inverse], dtype=np.float64)


def confusion_counts(kinds: NDArray[np.str_], classes: NDArray[np.int64]) -> NDArray[np.int64]:
    """(len(CONFUSION_KINDS), len(TRACK_CLASSES)) track-frames by what each follows
    (``kinds``, (M,) names from ``CONFUSION_KINDS``) and its class (``classes``, (M,)
    indices into ``TRACK_CLASSES``)."""
    rows = np.array([CONFUSION_KINDS.index(str(k)) for k in kinds], dtype=np.intp)
    n_cls = len(TRACK_CLASSES)
    flat = np.bincount(rows * n_cls + classes, minlength=len(CONFUSION_KINDS) * n_cls)
    return flat.reshape(len(CONFUSION_KINDS), n_cls).astype(np.int64)


def row_percentages(counts: NDArray[np.int64]) -> FloatArray:
    """Each row of a confusion matrix as a share of its total [%]; NaN for an empty row."""
    total = counts.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, 100.0 * counts / total, np.nan)


class StaticLives(NamedTuple):
    """Per track (in order of id): whether it holds still on the static world, its time
    from birth to its first static class (NaN if never) and its life (last row less
    first row) [s]; and per track-frame, its track's index (``track_of``)."""

    still: NDArray[np.bool_]
    to_class: FloatArray
    life: FloatArray
    track_of: NDArray[np.intp]


def static_lives(
    t: FloatArray,
    ids: NDArray[np.int64],
    classes: NDArray[np.int64],
    positions: FloatArray,
    updated: NDArray[np.bool_],
    on_static: NDArray[np.bool_],
    still_m: float,
    seen_s: float = 1.0,
) -> StaticLives:
    """Which tracks hold still on the static world (see the module docstring) and when
    each was first classed static.

    updated: (M,) whether a cluster updated each track-frame; on_static: (M,) whether
    it follows ``none`` or a static object.
    """
    _, first_row, inverse = np.unique(ids, return_index=True, return_inverse=True)
    n = len(first_row)
    born = t[first_row]
    last = np.full(n, -np.inf)
    np.maximum.at(last, inverse, t)
    wander = np.linalg.norm(positions - positions[first_row][inverse], axis=1)
    farthest = np.zeros(n)
    np.maximum.at(farthest, inverse[updated], np.nan_to_num(wander[updated], nan=np.inf))
    first_seen, last_seen = np.full(n, np.inf), np.full(n, -np.inf)
    np.minimum.at(first_seen, inverse[updated], t[updated])
    np.maximum.at(last_seen, inverse[updated], t[updated])
    elsewhere = np.bincount(inverse, weights=(~on_static).astype(float), minlength=n) > 0
    classed = np.full(n, np.inf)
    static = classes == _STATIC
    np.minimum.at(classed, inverse[static], t[static])
    watched = last_seen - first_seen >= seen_s - TIME_TOL_S
    still = ~elsewhere & (farthest <= still_m) & watched
    to_class = np.where(np.isfinite(classed), classed - born, np.nan)
    return StaticLives(still, to_class, last - born, inverse.astype(np.intp))


def static_held_s(locked: NDArray[np.bool_], lives: StaticLives, period: float) -> float:
    """How long the turret's lock was on a track that holds still on the static world
    [s]: its locked track-frames times the frame ``period`` [s]."""
    return float(np.count_nonzero(locked & lives.still[lives.track_of]) * period)


def _pct(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def followed_kinds(objects: ObjectsLog, tracks: TracksLog, radius: float) -> NDArray[np.str_]:
    """(M,) per row of ``tracks``, the kind of the truth object it follows (``none``
    where none is within ``radius`` [m])."""
    if len(objects) == 0 or objects.kinds is None:
        raise ValueError("class figures need every object's truth, frame by frame")
    rows = tracks.rows
    frame_of = np.clip(np.searchsorted(objects.t, rows["t"]), 0, len(objects) - 1)
    if len(rows) and not np.allclose(objects.t[frame_of], rows["t"]):
        raise ValueError("tracks logged at times without object truth")
    followed = followed_objects(frame_of, rows["position"], objects.positions, radius)
    names = np.array([*objects.kinds, NONE], dtype=np.str_)
    return names[followed]  # −1: the last, none


def confusion_figures(kinds: NDArray[np.str_], classes: NDArray[np.int64]) -> dict[str, Any]:
    """``confusion``, {kind: {class: track-frames}} over every kind of
    ``CONFUSION_KINDS``, and per kind ``<kind>_as_drone_pct``, the share of its
    track-frames classed drone (None without any)."""
    counts = confusion_counts(kinds, classes)
    shares = row_percentages(counts)
    out: dict[str, Any] = {
        "confusion": {
            kind: {cls: int(n) for cls, n in zip(TRACK_CLASSES, counts[i], strict=True)}
            for i, kind in enumerate(CONFUSION_KINDS)
        }
    }
    for i, kind in enumerate(CONFUSION_KINDS):
        out[f"{kind}_as_drone_pct"] = _pct(shares[i, _DRONE])
    return out


def static_figures(to_class: FloatArray, life: FloatArray, within_s: float) -> dict[str, Any]:
    """Of the tracks holding still on the static world, each with its time to class
    (NaN if never) and its life [s]: ``static_tracks``, ``static_classed`` (classed
    static at some time), ``static_to_class_median_s`` and ``static_to_class_max_s`` over
    those classed (None without any), and ``static_late``: those not classed static
    within ``within_s`` of their birth although they lived that long."""
    known = to_class[np.isfinite(to_class)]
    # to_class ≤ within_s, both differences of stamps (18.7 − 15.7 = 3.0000000000000018 s)
    late = np.where(
        np.isfinite(to_class), to_class > within_s + TIME_TOL_S, life >= within_s - TIME_TOL_S
    )
    return {
        "static_tracks": len(to_class),
        "static_classed": len(known),
        "static_to_class_median_s": float(np.median(known)) if len(known) else None,
        "static_to_class_max_s": float(known.max()) if len(known) else None,
        "static_late": int(np.count_nonzero(late)),
    }


def class_figures(
    objects: ObjectsLog,
    tracks: TracksLog,
    radius: float,
    *,
    min_age_s: float = 2.0,
    still_m: float | None = None,
    static_within_s: float = 3.0,
) -> dict[str, Any]:
    """metrics.json's ``classes`` (see the module docstring): the ``radius_m`` and
    ``min_age_s`` it was counted with, ``confusion_figures`` of the track-frames at
    least ``min_age_s`` old, and ``static_figures`` of the tracks that hold still on the
    static world (within ``still_m``: the radius unless given), and ``static_held_s``:
    how long the turret's lock was on one of them."""
    rows = tracks.rows
    kinds = followed_kinds(objects, tracks, radius)
    counted = track_ages(rows["t"], rows["id"]) >= min_age_s
    on_static = (kinds == NONE) | (kinds == "static")
    lives = static_lives(
        rows["t"],
        rows["id"],
        rows["cls"],
        rows["position"],
        rows["updated"],
        on_static,
        radius if still_m is None else still_m,
    )
    still = lives.still
    # every frame has a row of truth; a frame without tracks has none in ``rows``
    period = float(np.median(np.diff(objects.t))) if len(objects) > 1 else 0.0
    return {
        "radius_m": radius,
        "min_age_s": min_age_s,
        **confusion_figures(kinds[counted], rows["cls"][counted]),
        **static_figures(lives.to_class[still], lives.life[still], static_within_s),
        "static_held_s": static_held_s(rows["locked"].astype(bool), lives, period),
    }
