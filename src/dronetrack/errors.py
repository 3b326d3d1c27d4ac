"""The exceptions of dronetrack.

Library code raises these with a message that names the bad value; it never prints
or exits.  The command line turns them into one error line and exit code 2.
"""

from __future__ import annotations

__all__ = [
    "ConfigError",
    "DecodeError",
    "DeviceError",
    "DronetrackError",
    "InputError",
    "MissingExtraError",
    "RecordingError",
    "RunInterruptedError",
    "SapientProtocolError",
    "ScenarioError",
    "SensorError",
    "TrajectoryError",
]


class DronetrackError(Exception):
    """Base class of every error dronetrack raises on purpose."""


class ConfigError(DronetrackError):
    """A configuration value or file is invalid."""


class ScenarioError(ConfigError):
    """A scenario name or scenario file is invalid."""


class SensorError(ConfigError):
    """A sensor name, scan-pattern file or sensor parameter is invalid."""


class TrajectoryError(ConfigError):
    """A trajectory definition or trajectory file is invalid."""


class InputError(DronetrackError):
    """Input data (arrays, files) do not have the expected shape or content."""


class RecordingError(InputError):
    """A recording (bag, MCAP, point-cloud folder) cannot be opened or read as asked."""


class DecodeError(InputError):
    """One message's bytes do not decode (bad layout, counts that disagree with the length)."""


class SapientProtocolError(DecodeError):
    """A SAPIENT peer's bytes break the framing or do not parse as a ``SapientMessage``."""


class DeviceError(DronetrackError):
    """A device (LiDAR, servo, pan-tilt unit) cannot be reached, stops answering, or
    answers against its protocol; the message names the device."""


class MissingExtraError(DronetrackError):
    """An optional dependency is not installed; the message says which extra to install."""


class RunInterruptedError(DronetrackError):
    """A run that Ctrl-C (or SIGTERM) stopped, after it wrote what it had; the message
    ends the ``interrupted`` line, and the command line exits 130."""
