"""``--foxglove-port PORT``: a run served live to the Foxglove app over its WebSocket
protocol (foxglove-sdk's server; the optional extra ``[foxglove]``).

The topics and messages are those of the MCAP file (``sinks.foxglove.mcap_file``): the
frame's points and foreground, the particles, the estimate, truth and trail
markers, the turret's links as ``/tf``, and every object's track (``/tracks/markers``,
``/tracks``).  Their times are the host's wall clock
at the run's start plus the run's clock, so the app shows them as they come.  The
server listens on 127.0.0.1 (open ``ws://localhost:PORT`` in the app; from another
machine, forward the port, e.g. ``ssh -L PORT:localhost:PORT rig``).
"""

from __future__ import annotations

import time

from dronetrack.errors import ConfigError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.sinks.foxglove.mcap_file import FoxgloveChannels
from dronetrack.sinks.view import ViewerFeed
from dronetrack.types import Sample, StepResult

__all__ = ["FoxgloveServer"]

HOST = "127.0.0.1"


class FoxgloveServer(FoxgloveChannels):
    """A run's sink that serves every frame on ``ws://host:port``; ``close`` stops it.

    ``mount``: the turret's links for /tf (None: the sensor's pose alone).  A port that
    cannot be bound raises ``ConfigError`` naming it; a missing foxglove-sdk,
    ``MissingExtraError`` with the install hint.
    """

    def __init__(self, port: int, mount: MountGeometry | None = None, host: str = HOST) -> None:
        super().__init__(time.time(), f"the Foxglove server on port {port}")
        import foxglove

        try:
            self._server = foxglove.start_server(
                name="dronetrack", host=host, port=port, context=self._context
            )
        except (OSError, RuntimeError) as err:
            self._close_channels()
            raise ConfigError(f"--foxglove-port {port}: cannot serve on it ({err})") from None
        self.host = host
        self.port = int(self._server.port)
        self._feed = ViewerFeed([self], mount)

    @property
    def url(self) -> str:
        """Where the Foxglove app connects: ``ws://HOST:PORT``."""
        return f"ws://{self.host}:{self.port}"

    def write(self, sample: Sample, result: StepResult) -> None:
        """The run loop's sink: the frame as the viewers show it."""
        self._feed.write(sample, result)

    def close(self) -> None:
        """Stop serving; closing twice does nothing."""
        if self._closed:
            return
        self._closed = True
        self._server.stop()
        self._close_channels()
