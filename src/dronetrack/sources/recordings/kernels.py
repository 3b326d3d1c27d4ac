"""The numba kernels a replay needs besides the pipeline's, for ``warm_up``."""

from __future__ import annotations

import numpy as np

from dronetrack.formats.lzf import lzf_compress_literal, lzf_decompress
from dronetrack.pipeline.kernels import PIPELINE_WARM_UPS, WarmUpStep, synthetic_frame
from dronetrack.sources.truth import GroundTruth, target_point_count

__all__ = ["REPLAY_WARM_UPS", "replay_kernels"]


def replay_kernels() -> None:
    """A recording's ground-truth point count and PCD's LZF decoder."""
    frame = synthetic_frame()
    truth = GroundTruth(np.array([0.0, 0.1]), np.full((2, 3), 10.0))
    target_point_count(frame, frame.world_points(), truth, 1.0)
    data = bytes(range(40))
    lzf_decompress(np.frombuffer(lzf_compress_literal(data), dtype=np.uint8), len(data))


REPLAY_WARM_UPS: tuple[WarmUpStep, ...] = (*PIPELINE_WARM_UPS, replay_kernels)
