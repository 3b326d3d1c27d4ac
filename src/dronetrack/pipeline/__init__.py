"""The pipeline: one frame in, the tracks and the turret's command out.

- ``core``: ``Pipeline.step`` and ``run``, the one loop every job shares;
- ``factory``: the pipeline's components built from a validated configuration;
- ``kernels``: the numba kernels compiled (or loaded from numba's cache) before a
  timed loop.
"""

from dronetrack.pipeline.core import (
    Acquisition,
    OutlierSettings,
    Pipeline,
    RunStats,
    Stage,
    StepResult,
    run,
)

__all__ = ["Acquisition", "OutlierSettings", "Pipeline", "RunStats", "Stage", "StepResult", "run"]
