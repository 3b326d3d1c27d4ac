"""Zone alerts: a drone-class track that comes near a protected zone raises one.

For each drone-class track and zone the monitor keeps a level:

- ``inside``: the track is in the zone;
- ``margin``: it is within the zone's warning band (``margin_m``);
- ``predicted``: at its present velocity it enters the zone within ``margin_s``;
- none.

A level that rises is an alert at once, of the new level's kind.  A level that falls
must stay down for ``hold_s`` first, so a track on the band's edge does not chatter;
it is then an alert of the lower kind, or ``clear`` when nothing is left.  A track that
ends, or stops being classed drone, clears its alerts (the latter after ``hold_s`` too).
Birds, static objects and unknown tracks never raise one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, Tracks
from dronetrack.zones.shapes import Zone, entry_time

__all__ = ["ALERT_KINDS", "AlertEvent", "AlertMonitor", "zone_level"]

# The levels, lowest first; "clear" is an alert's end.
ALERT_KINDS = ("clear", "predicted", "margin", "inside")
_DRONE = TRACK_CLASSES.index("drone")


@dataclass(frozen=True, slots=True)
class AlertEvent:
    """An alert, or its clear: what a site is told."""

    t: float  # [s], the frame's end
    track_id: int
    zone: str
    kind: str  # one of ALERT_KINDS
    position: FloatArray  # (3,) world [m]
    velocity: FloatArray  # (3,) world [m/s]
    time_to_zone_s: float  # 0 inside, the entry time at the present velocity, else inf
    distance_m: float  # to the zone, 0 inside
    detail: str = ""  # why a clear came: "left", "track ended", "no longer a drone"


def zone_level(zone: Zone, p: FloatArray, v: FloatArray) -> tuple[int, float]:
    """The level (index into ALERT_KINDS) of a track at ``p`` moving at ``v`` for
    ``zone``, and its time to the zone [s] (inf when it does not enter within the
    margin's time, or the zone has none)."""
    if zone.contains(p):
        return 3, 0.0
    t_in = entry_time(zone, p, v, zone.margin_s) if zone.margin_s > 0 else math.inf
    if zone.in_margin(p):
        return 2, t_in
    return (1, t_in) if math.isfinite(t_in) else (0, t_in)


@dataclass
class _State:
    level: int
    lower: int  # the lower level seen since ``since`` (== level: none pending)
    since: float


class AlertMonitor:
    """The zones' alerts, frame by frame (``update``)."""

    def __init__(self, zones: Sequence[Zone], hold_s: float = 1.0) -> None:
        if hold_s < 0:
            raise ValueError(f"hold_s = {hold_s:g}: it cannot be negative")
        self.zones = tuple(zones)
        self.hold_s = hold_s
        self._states: dict[tuple[int, str], _State] = {}
        self._last: dict[int, tuple[FloatArray, FloatArray]] = {}  # each track's p, v

    @property
    def active(self) -> int:
        """Alerts raised and not cleared."""
        return sum(1 for s in self._states.values() if s.level > 0)

    def update(self, t: float, tracks: Tracks) -> list[AlertEvent]:
        """The alerts and clears of the frame ending at ``t`` [s] with ``tracks``."""
        if not self.zones:
            return []
        events: list[AlertEvent] = []
        alive = set()
        for k in range(len(tracks)):
            track_id = int(tracks.ids[k])
            alive.add(track_id)
            p, v = tracks.positions[k], tracks.velocities[k]
            self._last[track_id] = (p, v)
            drone = int(tracks.classes[k]) == _DRONE if len(tracks.classes) else False
            for zone in self.zones:
                level, t_in = zone_level(zone, p, v) if drone else (0, math.inf)
                event = self._step((track_id, zone.name), t, level)
                if event is not None:
                    kind, detail = event
                    if kind == "clear" and not drone:
                        detail = "no longer a drone"
                    events.append(
                        AlertEvent(
                            t,
                            track_id,
                            zone.name,
                            kind,
                            p.copy(),
                            v.copy(),
                            t_in,
                            zone.distance(p),
                            detail,
                        )
                    )
        for key in [key for key in self._states if key[0] not in alive]:
            state = self._states.pop(key)
            p, v = self._last[key[0]]
            if state.level > 0:
                zone = next(z for z in self.zones if z.name == key[1])
                events.append(
                    AlertEvent(
                        t,
                        key[0],
                        key[1],
                        "clear",
                        p.copy(),
                        v.copy(),
                        math.inf,
                        zone.distance(p),
                        "track ended",
                    )
                )
        for gone in [i for i in self._last if i not in alive]:
            del self._last[gone]
        return events

    def _step(self, key: tuple[int, str], t: float, level: int) -> tuple[str, str] | None:
        """Move one track's level for one zone; the alert it makes, if any."""
        state = self._states.get(key)
        if state is None:
            if level == 0:
                return None
            self._states[key] = _State(level, level, t)
            return ALERT_KINDS[level], ""
        if level > state.level:
            state.level = state.lower = level
            state.since = t
            return ALERT_KINDS[level], ""
        if level == state.level:
            state.lower, state.since = level, t
            return None
        # lower: wait hold_s at levels below the present one, then take the highest seen
        if state.lower == state.level:
            state.lower, state.since = level, t
        else:
            state.lower = max(state.lower, level)
        if t - state.since < self.hold_s - 1e-9:
            return None
        state.level = state.lower
        if state.level == 0:
            del self._states[key]
            return "clear", "left"
        return ALERT_KINDS[state.level], ""
