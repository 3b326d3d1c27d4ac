"""What a scenario's ``[sensor]`` section says of a spinning head (the VLP-16): its spin
rate, how its head is mounted, and how a live run cuts its stream into frames.

- Spin: ``rpm``, 600 unless set (the simulator's and the sensor's default).
- Mount: ``vlp16`` stands upright; ``vlp16-side`` lies on its side as seed 003 mounted
  it, rolled +90° about its forward x axis, so a point p_head in the head's own frame
  is p = R_x(90°) p_head in the frame the pipeline uses (the simulator's
  ``sim.mounted.side_mount``, which its tests check against this).
- Frames: an upright VLP-16 whose integration time is one revolution (60/rpm s; the
  default 0.1 s at 600 rpm) gets one frame per revolution, cut where the azimuth
  passes 0° (straight ahead, the sensor's x axis), as the simulator's frames of one
  revolution start there; on its side (seed 003 integrates over a fixed time while
  the turret sweeps), or with another integration time, frames of the integration
  time, cut by the points' own times.
"""

from __future__ import annotations

import math

from dronetrack.config.run import SensorConfig
from dronetrack.geometry.transforms import FloatArray, rot_x

__all__ = ["DEFAULT_RPM", "SPINNING", "head_rotation", "revolution_frames", "spin_rpm"]

DEFAULT_RPM = 600.0
SPINNING = ("vlp16", "vlp16-side")
SIDE_ROLL_RAD = 0.5 * math.pi


def spin_rpm(sensor: SensorConfig) -> float:
    """The head's spin rate [rpm]."""
    return DEFAULT_RPM if sensor.rpm is None else float(sensor.rpm)


def head_rotation(model: str) -> FloatArray | None:
    """R with p = R p_head for a sensor mounted other than upright (None: upright)."""
    if model.strip().lower() == "vlp16-side":
        return rot_x(SIDE_ROLL_RAD)
    return None


def revolution_frames(sensor: SensorConfig) -> bool:
    """True when a live run cuts this sensor's frames per revolution (module docstring)."""
    if sensor.model.strip().lower() != "vlp16":
        return False
    revolution = 60.0 / spin_rpm(sensor)
    return math.isclose(sensor.integration_time_s, revolution, rel_tol=1e-9)
