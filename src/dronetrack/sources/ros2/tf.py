"""A transform tree from ``/tf`` and ``/tf_static``, looked up at any time.

Each frame has one parent.  An edge is static (one parent_T_child) or a time
series of samples, interpolated between them (translation linearly, rotation by
nlerp, as ``geometry.interpolate_poses``; quaternions computed once per edge)
and held beyond the first and last.

    root_T_frame(t) = root_T_a(t) · a_T_b(t) · … · y_T_frame(t)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.errors import RecordingError
from dronetrack.geometry.transforms import (
    FloatArray,
    align_hemispheres,
    interpolate_quaternions,
    make_pose,
    matrix_to_quaternion,
    quaternion_to_matrix,
)

__all__ = ["TransformBuffer", "transform_matrix", "valid_transform"]


def transform_matrix(translation: ArrayLike, quaternion_xyzw: ArrayLike) -> FloatArray:
    """parent_T_child (4, 4) from a ROS translation and quaternion (x, y, z, w)."""
    x, y, z, w = np.asarray(quaternion_xyzw, dtype=np.float64)
    return make_pose(quaternion_to_matrix(np.array([w, x, y, z])), translation)


# |q| outside this range is not a rotation a ROS node meant to send (a damaged message)
QUATERNION_NORM_RANGE = (0.5, 2.0)


def valid_transform(t: float, translation: ArrayLike, quaternion_xyzw: ArrayLike) -> bool:
    """Whether a transform sample is usable: finite time, translation and quaternion,
    and 0.5 ≤ |q| ≤ 2 (it is normalised when used)."""
    p = np.asarray(translation, dtype=np.float64)
    q = np.asarray(quaternion_xyzw, dtype=np.float64)
    if p.shape != (3,) or q.shape != (4,) or not math.isfinite(t):
        return False
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        return False
    # |q| from its largest component, so that huge values cannot overflow
    m = float(np.max(np.abs(q)))
    norm = m * float(np.linalg.norm(q / m)) if m > 0 else 0.0
    return QUATERNION_NORM_RANGE[0] <= norm <= QUATERNION_NORM_RANGE[1]


@dataclass(slots=True)
class _Edge:
    parent: str
    static: FloatArray | None = None  # (4, 4)
    t: list[float] = field(default_factory=list)
    p: list[tuple[float, float, float]] = field(default_factory=list)
    q: list[tuple[float, float, float, float]] = field(default_factory=list)  # (w, x, y, z)
    # Sorted times (K,), quaternions (K, 4) in one hemisphere chain, translations (K, 3).
    table: tuple[FloatArray, FloatArray, FloatArray] | None = None

    def samples(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        if self.table is None:
            t = np.asarray(self.t, dtype=np.float64)
            order = np.argsort(t, kind="stable")
            q = align_hemispheres(np.asarray(self.q, dtype=np.float64)[order])
            self.table = (t[order], q, np.asarray(self.p, dtype=np.float64)[order])
        return self.table

    def at(self, times: FloatArray) -> FloatArray:
        """parent_T_child at ``times``, (n, 4, 4)."""
        if not self.t:
            assert self.static is not None
            return np.broadcast_to(self.static, (len(times), 4, 4))
        ts, q, p = self.samples()
        if len(ts) == 1:
            return np.broadcast_to(make_pose(quaternion_to_matrix(q[0]), p[0]), (len(times), 4, 4))
        R, pt = interpolate_quaternions(ts, q, p, times)
        return make_pose(R, pt)


class TransformBuffer:
    """parent_T_child edges by child frame; ``lookup`` composes a chain."""

    def __init__(self) -> None:
        self._edges: dict[str, _Edge] = {}
        self.conflicts = 0  # samples that gave a frame a second parent (ignored)
        self.invalid = 0  # samples with a non-finite value or a quaternion far from unit

    def __len__(self) -> int:
        return len(self._edges)

    def __contains__(self, frame: object) -> bool:
        return frame in self._edges or any(e.parent == frame for e in self._edges.values())

    def add(self, parent: str, child: str, t: float, T: FloatArray, static: bool = False) -> None:
        """Add parent_T_child (4, 4), at time ``t`` [s] unless ``static``."""
        w, x, y, z = matrix_to_quaternion(np.asarray(T)[:3, :3])
        self.add_transform(parent, child, t, np.asarray(T)[:3, 3], (x, y, z, w), static)

    def add_transform(
        self,
        parent: str,
        child: str,
        t: float,
        translation: ArrayLike,
        quaternion_xyzw: ArrayLike,
        static: bool = False,
    ) -> None:
        """Add a ROS transform (translation, quaternion x, y, z, w), at ``t`` unless ``static``.

        A sample with a non-finite value, or whose quaternion is not near unit length
        (ROS requires unit quaternions), is counted in ``invalid`` and left out.
        """
        if not valid_transform(t, translation, quaternion_xyzw):
            self.invalid += 1
            return
        edge = self._edges.get(child)
        if edge is None:
            edge = self._edges[child] = _Edge(parent)
        elif edge.parent != parent:
            self.conflicts += 1
            return
        if static:
            edge.static = transform_matrix(translation, quaternion_xyzw)
            return
        x, y, z, w = (float(v) for v in np.asarray(quaternion_xyzw, dtype=np.float64))
        px, py, pz = (float(v) for v in np.asarray(translation, dtype=np.float64))
        edge.t.append(float(t))
        edge.p.append((px, py, pz))
        edge.q.append((w, x, y, z))
        edge.table = None

    def frames(self) -> list[str]:
        """Every frame of the tree, sorted."""
        names = set(self._edges) | {e.parent for e in self._edges.values()}
        return sorted(names)

    def root(self, frame: str) -> str:
        """The top of ``frame``'s tree."""
        return self.chain(frame)[0] if frame in self._edges else frame

    def chain(self, frame: str, root: str | None = None) -> list[str]:
        """Frames from ``root`` (default: the top of the tree) down to ``frame``."""
        path = [frame]
        while path[-1] != root and path[-1] in self._edges:
            path.append(self._edges[path[-1]].parent)
            if len(path) > len(self._edges) + 1:
                raise RecordingError(f"the /tf tree has a loop through {frame!r}")
        if root is not None and path[-1] != root:
            listed = ", ".join(self.frames()) or "none"
            if root not in self:
                raise RecordingError(
                    f"frame {root!r} is not in the /tf tree; its frames are: {listed}"
                )
            raise RecordingError(
                f"frame {frame!r} is not below {root!r} in the /tf tree (its chain is "
                f"{' → '.join(path[::-1])}); the tree's frames are: {listed}"
            )
        return path[::-1]

    def lookup(self, root: str, frame: str, times: ArrayLike) -> FloatArray:
        """root_T_frame (n, 4, 4) at ``times`` [s]."""
        tq = np.atleast_1d(np.asarray(times, dtype=np.float64))
        out = np.broadcast_to(np.eye(4), (len(tq), 4, 4)).copy()
        for child in self.chain(frame, root)[1:]:
            out = out @ self._edges[child].at(tq)
        return out

    def newest(self, root: str, frame: str) -> float | None:
        """The time of the oldest newest sample of the moving edges between ``root``
        and ``frame``: how far the chain is known (None if it has no moving edge)."""
        ends = [max(self._edges[c].t) for c in self.chain(frame, root)[1:] if self._edges[c].t]
        return min(ends) if ends else None

    def prune(self, before: float) -> None:
        """Forget moving samples older than ``before`` [s], keeping the last one before it
        on each edge (a live buffer's history stays bounded)."""
        for edge in self._edges.values():
            if len(edge.t) < 2 or edge.t[1] >= before:
                continue
            ts = np.asarray(edge.t)
            keep = max(int(np.searchsorted(ts, before, side="right")) - 1, 0)
            if keep == 0 or np.any(np.diff(ts) < 0):
                continue  # nothing to drop, or out of order: left as it is
            edge.t, edge.p, edge.q = edge.t[keep:], edge.p[keep:], edge.q[keep:]
            edge.table = None

    def sample_times(self, root: str, frame: str, t0: float, t1: float) -> FloatArray:
        """Times of the moving edges' samples between ``root`` and ``frame`` in (t0, t1)."""
        found = []
        for child in self.chain(frame, root)[1:]:
            edge = self._edges[child]
            if edge.t:
                ts = edge.samples()[0]
                found.append(ts[(ts > t0) & (ts < t1)])
        if not found:
            return np.empty(0)
        return np.unique(np.concatenate(found))
