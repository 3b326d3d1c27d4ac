"""What a source knows of the objects in its world (the pipeline never sees it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol, get_args

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types.frames import Frame

__all__ = ["OBJECT_KINDS", "ObjectKind", "ObjectTruth", "Truth", "truth_objects"]


ObjectKind = Literal["drone", "bird", "walker", "vehicle", "static"]
OBJECT_KINDS: tuple[str, ...] = get_args(ObjectKind)


@dataclass(frozen=True, slots=True)
class ObjectTruth:
    """Every object a source knows of during a frame, K of them, and which object each
    of the frame's N returns came from (the simulator fills it; sinks and evaluation read
    it through ``truth_objects``).

    ids: (K,) a number that stays with an object for the whole run.  The simulator
        numbers its drones 0..D−1 in target order (0: the ``[drone]`` and
        ``[trajectory]`` target, then the ``[[targets]]`` entries), its birds after them,
        then its walkers and its vehicles (``[[walkers]]``, ``[[vehicles]]``, in order).
    kinds: (K,) each object's kind, one of ``OBJECT_KINDS``.
    positions: (K, 3) world position at the frame's end [m]; NaN while not present.
    velocities: (K, 3) world velocity at the frame's end [m/s]; NaN while not present.
    present: (K,) whether the object is in the world at the frame's end (a drone
        enters at its start time, a vehicle as it starts to drive in).
    object_index: (N,) per return of the frame, the index into these K arrays of the
        object it came from; −1 for anything else (the scene, a false alarm).

    The same objects, in the same order, describe every frame of a run.  The arrays
    are read-only.
    """

    ids: NDArray[np.int64]
    kinds: NDArray[np.str_]
    positions: FloatArray
    velocities: FloatArray
    present: NDArray[np.bool_]
    object_index: NDArray[np.int64]

    def __post_init__(self) -> None:
        k = len(self.ids)
        n = len(self.object_index)
        for name, shape, dtype in (
            ("ids", (k,), np.int64),
            ("kinds", (k,), np.str_),
            ("positions", (k, 3), np.float64),
            ("velocities", (k, 3), np.float64),
            ("present", (k,), np.bool_),
            ("object_index", (n,), np.int64),
        ):
            out = np.array(getattr(self, name), dtype=dtype)
            if out.shape != shape:
                raise InputError(f"object truth {name}: expected shape {shape}, got {out.shape}")
            out.flags.writeable = False
            object.__setattr__(self, name, out)
        unknown = sorted(set(self.kinds.tolist()) - set(OBJECT_KINDS))
        if unknown:
            raise InputError(
                f"object truth: unknown kind {unknown[0]!r}; one of {', '.join(OBJECT_KINDS)}"
            )
        if n and (self.object_index.min() < -1 or self.object_index.max() >= k):
            raise InputError(f"object truth: object_index must lie in [-1, {k}), one does not")

    def __len__(self) -> int:
        return len(self.ids)

    def returns(self) -> NDArray[np.int64]:
        """(K,) how many of the frame's returns came from each object."""
        hit = self.object_index[self.object_index >= 0]
        counts: NDArray[np.int64] = np.bincount(hit, minlength=len(self)).astype(np.int64)
        return counts

    def of_kind(self, kind: str) -> NDArray[np.bool_]:
        """(K,) which objects are of ``kind``."""
        mask: NDArray[np.bool_] = self.kinds == kind
        return mask


class Truth(Protocol):
    """What a source knows of the target during a frame (the simulator, or a
    recording's ground truth); the pipeline never sees it, only the sinks do.

    A source that knows of more than the target adds an ``objects`` member, an
    ``ObjectTruth``; read it with ``truth_objects``, which gives None for a truth
    without one.
    """

    @property
    def target_position(self) -> FloatArray:
        """(3,) world position at the frame's end [m]; NaN where unknown."""
        ...

    def target_returns(self, frame: Frame, world: FloatArray) -> int:
        """How many of the frame's returns hit the target, given the returns in the world
        frame (``world`` (N, 3), empty if the pipeline could not place them); -1 unknown."""
        ...


def truth_objects(truth: Truth | None) -> ObjectTruth | None:
    """The truth's every object (its ``objects`` member), None if it has none."""
    objects = getattr(truth, "objects", None)
    return objects if isinstance(objects, ObjectTruth) else None
