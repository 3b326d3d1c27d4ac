"""What a run tells its site: the zones' alerts (``alerts.jsonl``, a line each on the
console of a live run) and, with ``--sapient``, every track and alert to a C2 system.

``SiteFeed`` is a sink: after each tracking frame it runs the zones' ``AlertMonitor``
on the frame's tracks, writes each alert as a JSON line, says it in one line, and hands
the frame and its alerts to the SAPIENT node.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any, Protocol

from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.types import Sample, StepResult
from dronetrack.zones import AlertEvent, AlertMonitor

__all__ = ["ALERTS_FILE", "SiteFeed", "SiteLink", "alert_line", "alert_record", "alert_text"]

ALERTS_FILE = "alerts.jsonl"


class SiteLink(Protocol):
    """A C2 link (``sinks.sapient.node``): told of each tracking frame and its alerts."""

    def frame(self, sample: Sample, result: StepResult, alerts: list[AlertEvent]) -> None: ...

    def close(self) -> None: ...


def alert_record(event: AlertEvent, site: SiteFrame | None, utc: float) -> dict[str, Any]:
    """An alert as alerts.jsonl writes it: run time ``t`` [s], wall-clock ``utc`` (Unix
    s), track, zone, kind, WGS-84 and world position, world velocity, time to the zone
    (null: not entering) and distance to it."""
    x, y, z = (float(a) for a in event.position)
    record: dict[str, Any] = {
        "t": round(event.t, 6),
        "utc": round(utc, 3),
        "track_id": event.track_id,
        "zone": event.zone,
        "kind": event.kind,
    }
    if site is not None:
        lat, lon, alt = site.geodetic(event.position)
        record.update(lat_deg=float(lat), lon_deg=float(lon), alt_m=round(float(alt), 3))
    record.update(
        x=round(x, 3),
        y=round(y, 3),
        z=round(z, 3),
        vx=round(float(event.velocity[0]), 3),
        vy=round(float(event.velocity[1]), 3),
        vz=round(float(event.velocity[2]), 3),
        time_to_zone_s=round(event.time_to_zone_s, 3)
        if math.isfinite(event.time_to_zone_s)
        else None,
        distance_m=round(event.distance_m, 3),
    )
    if event.detail:
        record["detail"] = event.detail
    return record


_SAY = {
    "inside": "is inside zone",
    "margin": "is in the warning margin of zone",
    "predicted": "will enter zone",
    "clear": "clear of zone",
}


def alert_text(event: AlertEvent) -> str:
    """An alert in words, as the console and a C2 system are told it:
    ``drone track 7 is inside zone 'depot' at t = 33.8 s (in it)``, or for a clear
    ``track 7 clear of zone 'depot' (left)``."""
    if event.kind == "clear":
        why = f" ({event.detail})" if event.detail else ""
        return f"track {event.track_id} {_SAY['clear']} {event.zone!r}{why}"
    where = f"{event.distance_m:.0f} m from it" if event.kind != "inside" else "in it"
    eta = (
        f", {event.time_to_zone_s:.1f} s to the zone at its velocity"
        if event.kind != "inside" and math.isfinite(event.time_to_zone_s)
        else ""
    )
    return (
        f"drone track {event.track_id} {_SAY[event.kind]} {event.zone!r} "
        f"at t = {event.t:.1f} s ({where}{eta})"
    )


def alert_line(event: AlertEvent) -> str:
    """One line for the console: ``alert: drone track 7 is inside zone 'depot' ...``,
    ``clear: track 7 ...``."""
    return f"{'clear' if event.kind == 'clear' else 'alert'}: {alert_text(event)}"


class SiteFeed:
    """The sink that speaks to the site.  ``folder``: where alerts.jsonl goes (it is
    created at the first alert, and empty at ``close`` if none came while the folder
    exists); ``say``: told each alert's line (a live run prints it); ``link``: the
    SAPIENT node, if any."""

    def __init__(
        self,
        site: SiteFrame | None,
        monitor: AlertMonitor | None,
        folder: Callable[[], Path | None],
        say: Callable[[str], None] | None = None,
        link: SiteLink | None = None,
    ) -> None:
        self.site = site
        self.monitor = monitor
        self.folder = folder
        self.say = say
        self.link = link
        self._file: IO[str] | None = None

    def attach(self, pipeline: Any) -> None:
        """Give the link the pipeline, so that its look-at tasks reach the turret."""
        attach = getattr(self.link, "attach", None)
        if attach is not None:
            attach(pipeline)

    def write(self, sample: Sample, result: StepResult) -> None:
        events = []
        if result.phase == "track" and result.tracks is not None and self.monitor is not None:
            events = self.monitor.update(result.t, result.tracks)
        if events:
            self._write(events)
        if self.link is not None:  # the background scan's frames too: its status
            self.link.frame(sample, result, events)

    def _write(self, events: list[AlertEvent]) -> None:
        utc = time.time()
        out = self._open()
        for event in events:
            if out is not None:
                out.write(json.dumps(alert_record(event, self.site, utc)) + "\n")
            if self.say is not None:
                self.say(alert_line(event))
        if out is not None:
            out.flush()

    def _open(self) -> IO[str] | None:
        if self._file is None:
            folder = self.folder()
            if folder is not None:
                folder.mkdir(parents=True, exist_ok=True)
                self._file = (folder / ALERTS_FILE).open("a")
        return self._file

    def close(self) -> None:
        try:
            if self.link is not None:
                self.link.close()
        finally:
            if self._file is None and self.monitor is not None and self.monitor.zones:
                folder = self.folder()
                if folder is not None and folder.exists():
                    (folder / ALERTS_FILE).touch()
            if self._file is not None:
                self._file.close()
                self._file = None
