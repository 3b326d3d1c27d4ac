"""The pipeline: one frame in, the tracks and the turret's command out.

- ``core``: ``Pipeline.step``, one frame through every stage;
- ``selection``: which target the single-target tracker follows among the tracks;
- ``protect``: what the learning map must not learn (the tracks that may be a drone);
- ``loop``: ``run``, the one loop every job shares;
- ``factory``: the pipeline's components built from a validated configuration;
- ``kernels``: the numba kernels compiled (or loaded from numba's cache) before a
  timed loop.
"""

from dronetrack.pipeline.acquisition import Acquisition
from dronetrack.pipeline.core import OutlierSettings, Pipeline
from dronetrack.pipeline.loop import RunStats, Stage, run
from dronetrack.types import StepResult

__all__ = ["Acquisition", "OutlierSettings", "Pipeline", "RunStats", "Stage", "StepResult", "run"]
