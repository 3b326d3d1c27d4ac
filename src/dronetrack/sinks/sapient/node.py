"""dronetrack as a SAPIENT edge node: every track update a DetectionReport, every zone
alert an Alert, a StatusReport every ``status_period_s``, and look-at Tasks into the
turret's search.

What each message carries (``formats.sapient.messages`` builds them):

- DetectionReport, for each track a frame updated (static-class tracks are the
  background's business and are not reported): the object ID, a ULID fixed for the
  track's life; the WGS-84 location with its 1σ east, north and up errors from the
  track's covariance; range, azimuth (from true north) and elevation from the turret
  base with their 1σ errors, through the Jacobian of (az, el, r) in ENU; the ENU
  velocity with its errors; the class (drone, bird or unknown) with its confidence:
  p_drone for a drone, 1 − p_drone otherwise.  A track that ends gets a last report,
  state ``lost``, at its last location.
- Alert: WARNING for ``predicted`` and ``margin``, CRITICAL (high priority) for
  ``inside``, CLEAR for a clear; its location the track's, its associated detection
  the track's object ID.
- StatusReport, every ``status_period_s`` and when the mode changes: the node's
  location (the turret base), its field of view as a cone about the sensor's axis, its
  mode (``background scan`` while the map is scanned, then ``default``); GOODBYE when
  the run ends.
- A Task's look-at (a location, or a range and bearing from the node) is handed to
  the pipeline (``Pipeline.look_at``): the turret's next search is centred there.  It
  is acknowledged, or rejected with the reason (a replay has no turret to point; a
  turret mode that does not search).
"""

from __future__ import annotations

import math
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dronetrack.formats.sapient import messages as msgs
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sinks.sapient.link import SapientLink
from dronetrack.sinks.site_feed import alert_text
from dronetrack.types import Sample, StepResult, Tracks
from dronetrack.zones import AlertEvent

__all__ = ["CLASSES", "SapientNode", "aer_sigma", "node_uuid"]

Say = Callable[[str], None]
CLASSES = ("drone", "bird", "unknown")
_STATIC = "static"


def node_uuid(name: str, latitude_deg: float, longitude_deg: float) -> str:
    """A node ID fixed by the site's name and place, so that the same site keeps its
    ID from run to run: a UUID 5's hash, written as a version-4 UUID, the only form
    Apex's strict ID check accepts for node IDs."""
    key = f"dronetrack/{name}/{latitude_deg:.7f}/{longitude_deg:.7f}"
    return str(uuid.UUID(bytes=uuid.uuid5(uuid.NAMESPACE_URL, key).bytes, version=4))


def aer_sigma(enu: FloatArray, P: FloatArray) -> tuple[float, float, float]:
    """1σ of azimuth, elevation [°] and range [m] of an ENU position ``enu`` (3,) with
    covariance ``P`` (3, 3): Σ = J P Jᵀ with J the Jacobian of (az, el, r),
    az = atan2(e, n), el = atan2(u, ρ), r = ‖p‖, ρ = √(e² + n²)."""
    e, n, u = (float(a) for a in enu)
    rho2 = e * e + n * n
    r2 = rho2 + u * u
    if rho2 < 1e-12 or r2 < 1e-12:
        return math.nan, math.nan, math.sqrt(float(np.trace(P)))
    rho, r = math.sqrt(rho2), math.sqrt(r2)
    J = np.array(
        [
            [n / rho2, -e / rho2, 0.0],  # ∂az/∂(e, n, u)
            [-e * u / (r2 * rho), -n * u / (r2 * rho), rho / r2],  # ∂el/∂(e, n, u)
            [e / r, n / r, u / r],  # ∂r/∂(e, n, u)
        ]
    )
    s = np.sqrt(np.maximum(np.diag(J @ P @ J.T), 0.0))
    return math.degrees(s[0]), math.degrees(s[1]), float(s[2])


@dataclass
class _Object:
    object_id: str
    location: tuple[float, float, float]


class SapientNode:
    """The edge node on ``link``, for the site ``site``."""

    def __init__(
        self,
        link: SapientLink,
        site: SiteFrame,
        *,
        node_id: str,
        rng: np.random.Generator,
        status_period_s: float = 5.0,
        field_of_view_deg: tuple[float, float] = (70.4, 77.2),
        max_range_m: float = 190.0,
        steerable: bool = True,
        say: Say | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.link = link
        self.site = site
        self.node_id = node_id
        self.rng = rng
        self.status_period_s = status_period_s
        self.field_of_view_deg = field_of_view_deg
        self.max_range_m = max_range_m
        self.steerable = steerable
        self.say = say or (lambda text: None)
        self.clock = clock
        self._look_at: Callable[[float, FloatArray], bool] | None = None
        self._objects: dict[int, _Object] = {}
        self._status_at = -math.inf
        self._arrived = 0.0  # the frame in hand's arrival (``first_frames``)
        self._scanning = False  # the last status's mode: the background scan or not
        self._task: str | None = None  # the look-at task in hand
        self.reports = 0
        # Each object's first report sent: when its frame's last point arrived (a
        # live source's perf_counter), else when the node was given the frame; for
        # the first report's latency (``bench --live --sapient``)
        self.first_frames: dict[str, float] = {}

    def attach(self, pipeline: Any) -> None:
        """The pipeline whose turret a look-at task points (``Pipeline.look_at``)."""
        self._look_at = pipeline.look_at

    def frame(self, sample: Sample, result: StepResult, alerts: list[AlertEvent]) -> None:
        """Tell the fusion node of one frame: its tasks answered, the status when due
        (the background scan's frames too), each updated track and each alert."""
        now = self.clock()
        self._arrived = sample.received if sample.received is not None else time.perf_counter()
        self._answer_tasks(result.t, now)
        scanning = result.phase == "scan"
        if now - self._status_at >= self.status_period_s or scanning != self._scanning:
            self._scanning = scanning
            self._status(sample, now)
        if result.tracks is not None:
            self._reports(result.tracks, now, result.t)
        for event in alerts:
            self._alert(event, now)

    def close(self) -> None:
        """Say goodbye (a GOODBYE StatusReport), then close the link."""
        try:
            if self.link.stats.registered:
                goodbye = msgs.status_report(
                    self.node_id,
                    self.clock(),
                    report_id=msgs.new_ulid(self.rng, self.clock()),
                    location=self._node_location(),
                    pointing=None,
                    field_of_view_deg=self.field_of_view_deg,
                    ok=True,
                )
                goodbye.status_report.system = goodbye.status_report.SYSTEM_GOODBYE
                self.link.send(goodbye)
        finally:
            self.link.close()
            stats = self.link.stats
            self.say(
                f"sapient: {stats.sent} messages sent, {stats.dropped} dropped, "
                f"{stats.connects} connection{'s' if stats.connects != 1 else ''}"
            )

    # ------------------------------------------------------------------ messages

    def _node_location(self) -> tuple[float, float, float]:
        return (self.site.latitude_deg, self.site.longitude_deg, self.site.altitude_m)

    def _status(self, sample: Sample, now: float) -> None:
        axis = sample.frame.poses[-1][:3, 0]  # the sensor's x axis, world frame
        east, north, up = self.site.enu_vectors(axis)
        pointing = msgs.RangeBearing(
            math.degrees(math.atan2(east, north)) % 360.0,
            math.degrees(math.atan2(up, math.hypot(east, north))),
            self.max_range_m,
        )
        self._status_at = now
        self.link.send(
            msgs.status_report(
                self.node_id,
                now,
                report_id=msgs.new_ulid(self.rng, now),
                location=self._node_location(),
                pointing=pointing,
                field_of_view_deg=self.field_of_view_deg,
                mode="background scan" if self._scanning else "default",
                active_task=self._task,
            )
        )

    def _reports(self, tracks: Tracks, now: float, t: float) -> None:
        names = tracks.class_names
        alive = set()
        reported = [k for k in range(len(tracks)) if names[k] != _STATIC]
        if reported:
            lat, lon, alt = self.site.geodetic(tracks.positions[reported])
            az, el, rng = self.site.aer(tracks.positions[reported])
        for j, k in enumerate(reported):
            track_id = int(tracks.ids[k])
            alive.add(track_id)
            location = (float(lat[j]), float(lon[j]), float(alt[j]))
            obj = self._objects.get(track_id)
            if obj is None:
                obj = self._objects[track_id] = _Object(msgs.new_ulid(self.rng, now), location)
            obj.location = location
            if not tracks.updated[k]:
                continue
            self._send_report(tracks, k, names[k], obj, (az[j], el[j], rng[j]), now, t)
        for track_id in [i for i in self._objects if i not in alive]:
            self._lost(track_id, now)

    def _send_report(
        self,
        tracks: Tracks,
        k: int,
        cls: str,
        obj: _Object,
        aer: tuple[float, float, float],
        now: float,
        t: float,
    ) -> None:
        P = tracks.covariances[k]
        P_pos = self.site.enu_covariance(P[:3, :3])
        P_vel = self.site.enu_covariance(P[3:, 3:])
        sigma = np.sqrt(np.maximum(np.diag(P_pos), 0.0))
        s_az, s_el, s_r = aer_sigma(self.site.enu(tracks.positions[k]), P_pos)
        p = float(tracks.p_drone[k]) if len(tracks.p_drone) else math.nan
        sent = self.link.send(
            msgs.detection_report(
                self.node_id,
                now,
                report_id=msgs.new_ulid(self.rng, now),
                object_id=obj.object_id,
                location=obj.location,
                sigma_enu_m=sigma,
                range_bearing=msgs.RangeBearing(
                    float(aer[0]), float(aer[1]), float(aer[2]), s_az, s_el, s_r
                ),
                velocity_enu=self.site.enu_vectors(tracks.velocities[k]),
                velocity_sigma_enu=np.sqrt(np.maximum(np.diag(P_vel), 0.0)),
                classification=[(cls, p if cls == "drone" else 1.0 - p)],
                track_id=int(tracks.ids[k]),
                frame_t=t,
                task_id=self._task,
            )
        )
        self.reports += sent
        if sent:  # the first report that went out (not one dropped while the link was down)
            self.first_frames.setdefault(obj.object_id, self._arrived)

    def _lost(self, track_id: int, now: float) -> None:
        """The last report of a track that ended: state ``lost``, at its last location."""
        obj = self._objects.pop(track_id)
        msg = msgs.envelope(self.node_id, now)
        report = msg.detection_report
        report.report_id = msgs.new_ulid(self.rng, now)
        report.object_id, report.state = obj.object_id, "lost"
        report.location.CopyFrom(msgs.wgs84_location(*obj.location))
        report.track_info.add(type="track_id", value=str(track_id))
        self.link.send(msg)

    def _alert(self, event: AlertEvent, now: float) -> None:
        lat, lon, alt = self.site.geodetic(event.position)
        obj = self._objects.get(event.track_id)
        self.link.send(
            msgs.alert(
                self.node_id,
                now,
                alert_id=msgs.new_ulid(self.rng, now),
                active=event.kind != "clear",
                critical=event.kind == "inside",
                description=alert_text(event),  # as the console says it
                location=(float(lat), float(lon), float(alt)),
                object_id=None if obj is None else obj.object_id,
            )
        )

    def _answer_tasks(self, t: float, now: float) -> None:
        for task in self.link.tasks():
            wanted = msgs.look_at(task)
            reason: str | None = wanted if isinstance(wanted, str) else self._do(t, wanted)
            accepted = reason is None
            reasons = [] if reason is None else [reason]
            self.link.send(msgs.task_ack(self.node_id, now, task.task_id, accepted, reasons))
            what = "accepted" if accepted else f"rejected: {reason}"
            self.say(f"sapient: task {task.task_id[-6:]} {what}")

    def _do(self, t: float, wanted: msgs.LookAt) -> str | None:
        """Carry out a look-at; None if done, else why not."""
        if wanted.stop:
            self._task = None
            return None
        if not self.steerable or self._look_at is None:
            return "this run has no turret to point (a replay of a recording)"
        if wanted.point is not None:
            point = wanted.point
            alt = point.altitude if point.altitude is not None else self.site.altitude_m
            target = self.site.from_geodetic(point.latitude, point.longitude, alt)
        else:
            assert wanted.bearing is not None
            b = wanted.bearing
            target = self.site.from_aer(b.azimuth, b.elevation, b.range)
        if not self._look_at(t, target):
            return "the turret's mode does not search (fixed, external or a scan strategy)"
        self._task = wanted.task_id
        return None
