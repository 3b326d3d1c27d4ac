"""Protected zones and their alerts: a drone-class track near a zone, in it, or about
to enter it raises an alert (``alerts``); the zones' geometry is ``shapes``."""

from dronetrack.zones.alerts import ALERT_KINDS, AlertEvent, AlertMonitor, zone_level
from dronetrack.zones.shapes import Zone, circle, entry_time

__all__ = [
    "ALERT_KINDS",
    "AlertEvent",
    "AlertMonitor",
    "Zone",
    "circle",
    "entry_time",
    "zone_level",
]
