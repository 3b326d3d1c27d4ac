"""A VLP-16 in a live run (``velodyne://``): its client set up from the scenario's
sensor (the head's mount, ``config.spinning``), the frames it is cut into, and
``dronetrack info velodyne://…``."""

from __future__ import annotations

from dronetrack.config.run import SensorConfig
from dronetrack.config.spinning import head_rotation, revolution_frames, spin_rpm
from dronetrack.formats import velodyne as fv
from dronetrack.sources.live import OPEN_TIMEOUT_S, Assembler
from dronetrack.sources.revolutions import RevolutionAssembler
from dronetrack.sources.stream_sample import sample_stream
from dronetrack.sources.velodyne.client import VelodyneClient

__all__ = ["probe_velodyne", "velodyne_client", "velodyne_frames"]


def velodyne_client(uri: str, sensor: SensorConfig | None = None) -> VelodyneClient:
    """The (not yet opened) client of ``uri``, its points in the frame of ``sensor``'s
    mount (the head's own frame without one); ConfigError for a bad URI."""
    rotation = None if sensor is None else head_rotation(sensor.model)
    return VelodyneClient(uri, head_rotation=rotation)


def velodyne_frames(sensor: SensorConfig) -> tuple[float, Assembler | None]:
    """The frame period [s] a live run of ``sensor`` uses and what cuts its frames: one
    revolution, cut where the azimuth passes 0° (``revolution_frames``), or the
    integration time by the points' times (None: the live source's default)."""
    if revolution_frames(sensor):
        return 60.0 / spin_rpm(sensor), RevolutionAssembler()
    return sensor.integration_time_s, None


def probe_velodyne(uri: str, sample_s: float = 0.5) -> list[tuple[str, str]]:
    """``dronetrack info velodyne://…``: listen for ``sample_s`` seconds after the first
    packet and say what came, as (name, value) lines: the address listened on, the
    sensor's address, product and return mode (the factory bytes), the spin rate from
    the azimuths, and the packets, points, lost and malformed packets.  DeviceError if
    no packet comes within 5 s."""
    client = velodyne_client(uri)
    lines = [("listening", f"UDP {client.endpoint.bind_ip}:{client.endpoint.port}")]
    try:
        client.open(OPEN_TIMEOUT_S)
        sampled = sample_stream(client, sample_s)
        product = client.product
        mode = client.return_mode
        rpm = client.rpm
        lines += [
            ("device", f"{client.source_ip}"),
            (
                "product",
                "unknown (no well-formed packet)"
                if product is None
                else f"0x{product:02X} ({fv.PRODUCTS.get(product, 'unknown')})",
            ),
            (
                "return mode",
                "unknown"
                if mode is None
                else f"0x{mode:02X} ({fv.RETURN_MODES.get(mode, 'unknown')})",
            ),
            ("spin", "unknown" if rpm is None else f"{rpm:.0f} rpm"),
            sampled,
        ]
    finally:
        client.close()
    return lines
