"""Turret control: where the sensor should look after each frame.

- Scanning (building the background): a raster over the configured area.
- Tracking: aim at the estimate (seed 000's eq. 10, through the mount geometry),
  optionally ahead of it by ``lead_s`` of its velocity.  While not locked, aim at the
  detect stage's best confirmed candidate if there is one, so the tracker gets the
  dense centre on it.  Otherwise: before the first lock look at ``home`` for
  ``search_hold_s``; once the target is lost, follow the tracker's prediction for
  ``search_hold_s``.  Then search the field of regard (``control.search``): sweeps
  growing around that bearing, then a raster of the whole field, until a confirmed
  candidate or a lock brings it back to tracking.
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
from dronetrack.control.scan import raster
from dronetrack.control.search import SearchPath, search_path
from dronetrack.geometry.mount import MountGeometry
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Candidates, TrackEstimate, TurretCommand

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
        self,
        t: float,
        estimate: TrackEstimate,
        points: FloatArray | None = None,
        candidates: Candidates | None = None,
        cues: Candidates | None = None,
    ) -> TurretCommand | None:
        """The command after a tracking step; ``points`` is the frame's foreground (world),
        ``candidates`` the detect stage's confirmed candidates and ``cues`` its tentative
        tracks worth a look (None: acquisition off)."""
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
        search_lane: float = math.radians(20.0),
        search_rate: float = math.radians(40.0),
        search_area: tuple[tuple[float, float], tuple[float, float]] | None = None,
        cue_look_s: float = 0.5,
        scan_pan: tuple[float, float] = (math.radians(-60.0), math.radians(60.0)),
        scan_tilt: tuple[float, float] = (math.radians(-25.0), math.radians(5.0)),
        scan_period_s: float = 4.0,
        scan_end_s: float | None = None,
    ) -> None:
        """``search_pan``: the first search sweep's half-width; ``search_lane``: the
        sensor's dense centre (the raster's lane width); ``search_rate``: the search's
        angular rate; ``search_area``: (pan, tilt) ranges to search [rad], default the
        background scan's (all clipped to the joint limits); ``cue_look_s``: how long a
        look at a cue lasts at least."""
        self.mount = mount
        self.pan_limits = pan_limits
        self.tilt_limits = tilt_limits
        self.mode = mode
        self.home = aim_angles(np.asarray(home, dtype=np.float64), mount)
        self.lead_s = lead_s
        self.search_hold_s = search_hold_s
        area = search_area if search_area is not None else (scan_pan, scan_tilt)
        self.search_area = (_clip_range(area[0], pan_limits), _clip_range(area[1], tilt_limits))
        self.search = (search_pan, search_lane, search_rate)
        self.cue_look_s = cue_look_s
        self._look: tuple[float, tuple[float, float]] | None = None  # (until, aim) of a cue
        self.scan = (scan_pan, scan_tilt, scan_period_s)
        # The scan ends at home at scan_end_s [s] (None: the raster from t = 0 as it falls)
        self.scan_end = None if scan_end_s is None else (scan_end_s, *self.home)
        self._locked_once = False
        self._last_aim = self.home
        self._lost_since: float | None = None  # when the tracker last stopped being on it
        self._path: SearchPath | None = None
        self._fixed_sent = False
        self._task_aim: tuple[float, float] | None = None  # a look-at task's, until searched

    def look_at(self, t: float, point: FloatArray) -> bool:
        """Search around world ``point`` (3,) [m] from time ``t``: a look-at task.  A
        turret that is searching starts a new search centred there at once; one that
        follows a target goes on following it, and its next search starts there.  False
        in a mode that does not search (fixed, external, scan strategies)."""
        if self.mode != "tracking" or not np.all(np.isfinite(point)):
            return False
        self._task_aim = aim_angles(np.asarray(point, dtype=np.float64), self.mount)
        self._path, self._look = None, None
        if self._lost_since is not None:
            self._lost_since = t - self.search_hold_s  # the search begins with this frame
        return True

    def _command(self, t: float, pan: float, tilt: float) -> TurretCommand:
        pan = min(max(pan, self.pan_limits[0]), self.pan_limits[1])
        tilt = min(max(tilt, self.tilt_limits[0]), self.tilt_limits[1])
        return TurretCommand(t, pan, tilt)

    def scanning(self, t: float) -> TurretCommand:
        """The background-scan raster at time t."""
        pan, tilt, period = self.scan
        return self._command(t, *raster(t, pan, tilt, period, self.scan_end))

    def tracking(
        self,
        t: float,
        estimate: TrackEstimate,
        points: FloatArray | None = None,
        candidates: Candidates | None = None,
        cues: Candidates | None = None,
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
            self._path = None
            self._look = None
            return self._aim(t, estimate.position, estimate.velocity)
        if candidates is not None and len(candidates):
            # A confirmed candidate: put the dense centre on it; a search resumes from it.
            self._lost_since, self._path, self._look = t, None, None
            return self._aim(t, candidates.positions[0], candidates.velocities[0])
        if self._lost_since is None:
            self._lost_since = t
        if cues is not None and len(cues):
            # A tentative track: a look, at least cue_look_s long, puts the dense centre on
            # it, to confirm it or not.  No lead: two hits give a poor velocity.  The
            # search's clock runs on, so a false cue delays the search by the look only.
            aim = aim_angles(cues.positions[0], self.mount)
            self._look = (t + self.cue_look_s, aim)
        if self._look is not None and t < self._look[0]:
            self._last_aim = self._look[1]
            return self._command(t, *self._last_aim)
        lost_for = t - self._lost_since
        if lost_for < self.search_hold_s:
            if self._locked_once and np.all(np.isfinite(estimate.position)):
                return self._aim(t, estimate.position, estimate.velocity)  # the prediction
            return self._command(t, *self._last_aim)  # home, or the last candidate
        if self._path is None:
            first, lane, rate = self.search
            if self._task_aim is not None:  # a look-at task's point centres this search
                self._last_aim, self._task_aim = self._task_aim, None
            self._path = search_path(self._last_aim, *self.search_area, lane, first, rate)
        return self._command(t, *self._path.at(lost_for - self.search_hold_s))

    def _aim(self, t: float, position: FloatArray, velocity: FloatArray) -> TurretCommand:
        """Aim ahead by the lead time: p + v · lead."""
        target = position + self.lead_s * velocity
        self._last_aim = aim_angles(target, self.mount)
        return self._command(t, *self._last_aim)


def _clip_range(r: tuple[float, float], limits: tuple[float, float]) -> tuple[float, float]:
    lo, hi = max(r[0], limits[0]), min(r[1], limits[1])
    return (lo, hi) if lo < hi else (limits[0], limits[1])
