"""Turret control: where the sensor should look after each frame.

- Scanning (building the background): a raster over the configured area.
- Tracking: aim at the estimate (seed 000's eq. 10, through the mount geometry),
  optionally ahead of it by ``lead_s`` of its velocity.  Before the first lock
  look at ``home``.  Once the target is lost, hold on the last position for
  ``search_hold_s``, then sweep around the last bearing until it is found again.
- Fixed: look at ``home`` and never move (the ablation of seed 000 Table II).
- External: the pipeline scans the background, then leaves the turret to someone
  else (an operator, or the simulator's truth aimer for seed 000's Table III).

Every command is clipped to the turret's joint limits.
"""

from __future__ import annotations

import math
from typing import Literal, Protocol

import numpy as np

from dronetrack.control.aiming import aim_angles
from dronetrack.control.scan import raster, triangle
from dronetrack.geometry.mount import MountGeometry
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TrackEstimate, TurretCommand

__all__ = ["Controller", "TurretController"]

Mode = Literal["tracking", "fixed", "external"]


class Controller(Protocol):
    """What the pipeline asks of a turret controller."""

    @property
    def mode(self) -> str:
        """How the turret is driven (``tracking``, ``fixed``, ``external``, a scan strategy)."""
        ...

    @property
    def home(self) -> tuple[float, float]:
        """(pan, tilt) [rad] to hold before a lock, and when fixed."""
        ...

    def scanning(self, t: float) -> TurretCommand:
        """The command while the background is scanned."""
        ...

    def tracking(
        self, t: float, estimate: TrackEstimate, points: FloatArray | None = None
    ) -> TurretCommand | None:
        """The command after a tracking step; ``points`` is the frame's foreground (world)."""
        ...


class TurretController:
    """Turns estimates into turret goal angles (position commands)."""

    def __init__(
        self,
        mount: MountGeometry,
        pan_limits: tuple[float, float],
        tilt_limits: tuple[float, float],
        mode: Mode = "tracking",
        home: FloatArray | tuple[float, float, float] = (60.0, 0.0, 15.0),
        lead_s: float = 0.0,
        search_hold_s: float = 2.0,
        search_pan: float = math.radians(30.0),
        search_tilt: float = math.radians(10.0),
        search_period_s: float = 4.0,
        scan_pan: tuple[float, float] = (math.radians(-60.0), math.radians(60.0)),
        scan_tilt: tuple[float, float] = (math.radians(-25.0), math.radians(5.0)),
        scan_period_s: float = 4.0,
    ) -> None:
        self.mount = mount
        self.pan_limits = pan_limits
        self.tilt_limits = tilt_limits
        self.mode = mode
        self.home = aim_angles(np.asarray(home, dtype=np.float64), mount)
        self.lead_s = lead_s
        self.search_hold_s = search_hold_s
        self.search = (search_pan, search_tilt, search_period_s)
        self.scan = (scan_pan, scan_tilt, scan_period_s)
        self._locked_once = False
        self._last_aim = self.home
        self._lost_since: float | None = None
        self._fixed_sent = False

    def _command(self, t: float, pan: float, tilt: float) -> TurretCommand:
        pan = min(max(pan, self.pan_limits[0]), self.pan_limits[1])
        tilt = min(max(tilt, self.tilt_limits[0]), self.tilt_limits[1])
        return TurretCommand(t, pan, tilt)

    def scanning(self, t: float) -> TurretCommand:
        """The background-scan raster at time t."""
        pan, tilt, period = self.scan
        return self._command(t, *raster(t, pan, tilt, period))

    def tracking(
        self, t: float, estimate: TrackEstimate, points: FloatArray | None = None
    ) -> TurretCommand | None:
        """The command after a tracking step whose result is ``estimate``; None to stay put.

        ``points`` (this frame's foreground) is not needed to aim at the estimate.
        """
        if self.mode == "external":
            return None
        if self.mode == "fixed":
            if self._fixed_sent:
                return None
            self._fixed_sent = True
            return self._command(t, *self.home)
        if estimate.tracked:
            self._locked_once = True
            self._lost_since = None
            # Aim ahead by the lead time: p + v · lead
            target = estimate.position + self.lead_s * estimate.velocity
            self._last_aim = aim_angles(target, self.mount)
            return self._command(t, *self._last_aim)
        if not self._locked_once:
            return self._command(t, *self.home)
        if self._lost_since is None:
            self._lost_since = t
        lost_for = t - self._lost_since
        if lost_for < self.search_hold_s:
            return self._command(t, *self._last_aim)
        # Search: sweep ± the search span around the last bearing.
        pan_span, tilt_span, period = self.search
        s = lost_for - self.search_hold_s
        pan = self._last_aim[0] + triangle(s + period / 4, -pan_span, pan_span, period)
        tilt = self._last_aim[1] + triangle(
            s + period * math.pi / 4, -tilt_span, tilt_span, period * math.pi
        )
        return self._command(t, pan, tilt)
