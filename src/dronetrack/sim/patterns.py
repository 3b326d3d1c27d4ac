"""Scan patterns: when each pulse is fired and in which direction.

A pattern maps a time window to the pulses fired in it: times, unit directions
in the sensor frame (x forward, y left, z up), line/channel indices and the
beam origins in the sensor frame.  Patterns run continuously from t = 0, so the
pattern of a frame depends on its absolute time (Livox prisms never reset).

The patterns live by sensor family and are gathered here: ``Pulses`` and the
``ScanPattern`` protocol in ``dronetrack.sim.pulses``, the Risley prisms (Livox
Mid-40, Avia) in ``dronetrack.sim.risley``, the spinning heads (Velodyne VLP-16,
the Mid-360 model) in ``dronetrack.sim.spinning``, and recorded pattern tables in
``dronetrack.sim.pattern_files``.
"""

from __future__ import annotations

from dronetrack.sim.pattern_files import TablePattern, load_pattern_table
from dronetrack.sim.pulses import Pulses, ScanPattern
from dronetrack.sim.risley import (
    AVIA_INCIDENT,
    AVIA_PRISMS,
    MID40_PRISMS,
    RisleyPattern,
    avia_pattern,
    mid40_pattern,
    refract,
    risley_directions,
)
from dronetrack.sim.spinning import (
    MID360_PATTERN,
    VLP16_ELEVATION_DEG,
    VLP16_VERTICAL_OFFSET_MM,
    SinusoidalSpinPattern,
    SpinningPattern,
    vlp16_pattern,
)

__all__ = [
    "AVIA_INCIDENT",
    "AVIA_PRISMS",
    "MID40_PRISMS",
    "MID360_PATTERN",
    "VLP16_ELEVATION_DEG",
    "VLP16_VERTICAL_OFFSET_MM",
    "Pulses",
    "RisleyPattern",
    "ScanPattern",
    "SinusoidalSpinPattern",
    "SpinningPattern",
    "TablePattern",
    "avia_pattern",
    "load_pattern_table",
    "mid40_pattern",
    "refract",
    "risley_directions",
    "vlp16_pattern",
]
