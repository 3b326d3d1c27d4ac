"""dronetrack: detect and track small drones with LiDAR on a pan-tilt turret."""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
