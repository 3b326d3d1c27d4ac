"""What a live LiDAR says of itself (``dronetrack info livox://IP``, ``livox2://IP``,
``velodyne://PORT``): the device's own answers and a short sample of its stream."""

from __future__ import annotations

from typing import TYPE_CHECKING

from dronetrack.jobs.live.streams import OPEN_TIMEOUT_S, open_point_stream
from dronetrack.sources.stream_sample import sample_stream

if TYPE_CHECKING:
    from dronetrack.sources.livox.sdk2 import Livox2Client

__all__ = ["probe_lidar"]


def _sdk2_info(client: Livox2Client, unknown: str) -> list[tuple[str, str]]:
    """``info`` lines of an SDK 2 device's parameter inquiry (keys 0x8000-0x8006)."""
    info = client.query_info()
    serial = client.serial or (info.serial if info is not None else None)
    lines = [("serial number", serial or unknown)]
    if info is None:
        return [*lines, ("firmware", "no answer to the parameter inquiry (0x0101)")]
    state = None
    if info.work_state is not None:
        state = f"0x{info.work_state:02X} {info.work_state_name}"
    missing = "not reported"
    return [
        *lines,
        ("product", info.product or missing),
        ("firmware", info.firmware or missing),
        ("loader version", info.loader or missing),
        ("hardware version", info.hardware or missing),
        ("MAC", info.mac or missing),
        ("work state", state or missing),
    ]


def probe_lidar(uri: str, sample_s: float = 0.5) -> list[tuple[str, str]]:
    """What a Livox LiDAR says of itself (``dronetrack info livox://IP``, ``livox2://IP``),
    as (name, value) lines: model and device type from discovery; for SDK 1 the
    broadcast code and the firmware (the device-information query); for SDK 2 what
    its parameter inquiry reports (serial number, product, firmware, loader and
    hardware versions, MAC, work state); the host address and command port the
    connection announced, then what ``sample_s`` seconds of sampling bring (packets,
    points, lost and malformed packets).  DeviceError if it does not answer.  A VLP-16
    (``velodyne://``) is only listened to: ``jobs.live.velodyne.probe_velodyne``."""
    if uri.startswith("velodyne://"):
        from dronetrack.jobs.live.velodyne import probe_velodyne

        return probe_velodyne(uri, sample_s)
    from dronetrack.sources.livox.sdk1 import LivoxClient
    from dronetrack.sources.livox.sdk2 import Livox2Client

    client = open_point_stream(uri)
    assert isinstance(client, LivoxClient | Livox2Client)
    unknown = "unknown (no discovery answer)"
    lines: list[tuple[str, str]] = []
    try:
        client.connect(OPEN_TIMEOUT_S)
        lines.append(("device", client.name))
        lines.append(("device type", unknown if client.dev_type is None else str(client.dev_type)))
        if isinstance(client, LivoxClient):
            lines.append(("broadcast code", client.broadcast_code or unknown))
            firmware = client.query_firmware()
            lines.append(("firmware", firmware or "no answer to the device-information query"))
        else:
            lines.extend(_sdk2_info(client, unknown))
        lines.append(("host", f"{client.host_ip}, command port {client.cmd_port}"))
        client.open(OPEN_TIMEOUT_S)
        lines.append(sample_stream(client, sample_s))
    finally:
        client.close()
    return lines
