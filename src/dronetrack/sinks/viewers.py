"""Opening and closing the viewer writers, and what they share.

``open_viewers`` turns the CLI's ``--foxglove FILE.mcap`` and ``--rerun FILE.rrd``
into a list of ``ViewerSink``; ``close_viewers`` finishes every file.  Each SDK is
an optional extra, imported only when its writer is asked for; a missing one
raises ``MissingExtraError`` with a one-line install hint before any file is
created.

The helpers below hold what both writers show the same way: the particle
subsample, the estimate trail and the world pose of every frame of the
transform tree.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sinks.view import NamedTransform, ViewerSink, ViewFrame

__all__ = [
    "MAX_PARTICLES",
    "TRAIL_LENGTH",
    "WORLD_FRAME",
    "EstimateTrail",
    "checked",
    "close_viewers",
    "open_viewers",
    "subsample_particles",
    "world_poses",
    "xyz",
]

WORLD_FRAME = "world"
MAX_PARTICLES = 2000  # at most this many particles are drawn per frame
TRAIL_LENGTH = 50  # past estimates in the trail


def open_viewers(
    foxglove: Path | None, rerun: Path | None, *, start: float = 0.0
) -> list[ViewerSink]:
    """The writers asked for, in the order (Foxglove, rerun); none when both are None.

    ``start`` [s since the Unix epoch] is added to every frame's time for the
    files' timestamps: 0 for a simulation, the recording's clock for a replay.

    Both SDKs, and that both files can be written, are checked before any file is
    opened, so a missing extra or a bad path leaves no half-written file behind.  An
    existing file is overwritten.  A path that cannot be written raises a one-line
    ``ConfigError`` that names it.
    """
    # Imported here: the writer modules import the helpers of this module.
    from dronetrack.sinks.foxglove_out import FoxgloveWriter, require_foxglove
    from dronetrack.sinks.rerun_out import RerunWriter, require_rerun
    from dronetrack.sinks.run_folder import prepare_output_file

    if foxglove is not None:
        require_foxglove()
    if rerun is not None:
        require_rerun()
    if foxglove is not None:
        prepare_output_file(foxglove, "--foxglove")
    if rerun is not None:
        prepare_output_file(rerun, "--rerun")
    sinks: list[ViewerSink] = []
    try:
        if foxglove is not None:
            sinks.append(_opened(FoxgloveWriter, foxglove, start, "--foxglove"))
        if rerun is not None:
            sinks.append(_opened(RerunWriter, rerun, start, "--rerun"))
    except BaseException:
        close_viewers(sinks)
        raise
    return sinks


def _opened(
    writer: Callable[[Path, float], ViewerSink], path: Path, start: float, option: str
) -> ViewerSink:
    """``writer(path, start)``, with the SDK's own failure to create the file (an
    ``OSError`` or a ``RuntimeError`` from its native core) as a ``ConfigError``."""
    try:
        return writer(path, start)
    except (OSError, RuntimeError) as err:
        raise ConfigError(f"{option} {path}: cannot write it ({err})") from None


def close_viewers(sinks: Iterable[ViewerSink]) -> None:
    """Close every sink, even when one fails; then raise the first failure."""
    first: BaseException | None = None
    for sink in sinks:
        try:
            sink.close()
        except BaseException as err:
            if first is None:
                first = err
    if first is not None:
        raise first


def xyz(points: FloatArray | None, what: str) -> FloatArray:
    """``points`` as a (N, 3) float64 array; None and any empty array give (0, 3)."""
    if points is None:
        return np.zeros((0, 3))
    a = np.asarray(points, dtype=np.float64)
    if a.size == 0:
        return np.zeros((0, 3))
    if a.ndim == 1 and a.shape[0] == 3:
        return a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{what} must have shape (N, 3), got {a.shape}")
    return a


def _point(a: FloatArray | None, what: str) -> FloatArray | None:
    if a is None:
        return None
    p = xyz(a, what)
    if len(p) != 1:
        raise InputError(f"{what} must have shape (3,), got {np.shape(a)}")
    out: FloatArray = p[0]
    return out


def _matrix(tf: NamedTransform) -> NamedTransform:
    m = np.asarray(tf.matrix, dtype=np.float64)
    if m.shape != (4, 4):
        raise InputError(f"transform {tf.parent}->{tf.child} is {m.shape}, not (4, 4)")
    return NamedTransform(tf.parent, tf.child, m)


def checked(frame: ViewFrame) -> ViewFrame:
    """``frame`` with every array as float64 of the documented shape; ``InputError`` if not.

    Writers check a frame whole before they write any of it.  Points and
    particles come as (N, 3) (empty: (0, 3)), estimate and truth as (3,).
    """
    return dataclasses.replace(
        frame,
        points=xyz(frame.points, "points"),
        foreground=xyz(frame.foreground, "foreground"),
        estimate=_point(frame.estimate, "estimate"),
        truth=_point(frame.truth, "truth"),
        particles=None if frame.particles is None else xyz(frame.particles, "particles"),
        transforms=tuple(_matrix(tf) for tf in frame.transforms),
    )


def subsample_particles(particles: FloatArray | None, limit: int = MAX_PARTICLES) -> FloatArray:
    """Every k-th particle, k the smallest stride that keeps at most ``limit``."""
    p = xyz(particles, "particles")
    stride = max(1, math.ceil(len(p) / limit))
    out: FloatArray = p[::stride]
    return out


class EstimateTrail:
    """The last ``length`` estimates; a frame without an estimate ends the trail."""

    def __init__(self, length: int = TRAIL_LENGTH) -> None:
        self._points: deque[FloatArray] = deque(maxlen=length)

    def update(self, estimate: FloatArray | None) -> FloatArray:
        """Add this frame's estimate (or restart on None); the trail as (K, 3)."""
        if estimate is None:
            self._points.clear()
        else:
            self._points.append(np.array(estimate, dtype=np.float64).reshape(3))
        if not self._points:
            return np.zeros((0, 3))
        return np.stack(list(self._points))


def world_poses(
    transforms: Sequence[NamedTransform], root: str = WORLD_FRAME
) -> dict[str, FloatArray]:
    """root_T_child (4, 4) of every child in ``transforms``, composed along the tree.

    The edges may come in any order; an edge whose parent never connects to
    ``root`` raises ``InputError``.
    """
    poses: dict[str, FloatArray] = {root: np.eye(4)}
    pending = list(transforms)
    while pending:
        left: list[NamedTransform] = []
        for tf in pending:
            if tf.parent not in poses:
                left.append(tf)
            else:
                poses[tf.child] = poses[tf.parent] @ _matrix(tf).matrix
        if len(left) == len(pending):
            names = ", ".join(f"{tf.parent}->{tf.child}" for tf in left)
            raise InputError(f"transforms not connected to {root!r}: {names}")
        pending = left
    return {name: pose for name, pose in poses.items() if name != root}
