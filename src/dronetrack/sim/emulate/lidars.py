"""Which emulated LiDAR streams a scenario's sensor: a Livox SDK 1 device (Avia,
Mid-40), the SDK 2 Mid-360, or a Velodyne VLP-16 (upright or on its side), and the
URI a host opens it with."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from dronetrack.config.run import SensorConfig
from dronetrack.config.spinning import head_rotation, spin_rpm
from dronetrack.errors import ConfigError
from dronetrack.formats import velodyne as fv
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.sim.emulate.livox import AVIA, MID40, EmulatedLivox
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sim.emulate.livox_stream import PointSource, StreamingDevice
from dronetrack.sim.emulate.velodyne import EmulatedVelodyne

__all__ = [
    "DEVICES",
    "DeviceFactory",
    "LidarModel",
    "LivoxModel",
    "default_velodyne_dest",
    "host_uri",
    "lidar_device",
    "livox_device",
]

DeviceFactory = Callable[[PointSource], StreamingDevice]


@dataclass(frozen=True, slots=True)
class LidarModel:
    """An emulated LiDAR model: its name, the host's URI scheme and its protocol
    (``livox-sdk1``, ``livox-sdk2`` or ``velodyne``)."""

    name: str
    scheme: str
    protocol: str


LivoxModel = LidarModel  # its name before the VLP-16 came

# sensor model of a scenario → the device that streams it
DEVICES = {
    "avia": LidarModel("Livox Avia", "livox", "livox-sdk1"),
    "mid40": LidarModel("Livox Mid-40", "livox", "livox-sdk1"),
    "mid360": LidarModel("Livox Mid-360", "livox2", "livox-sdk2"),
    "vlp16": LidarModel("Velodyne VLP-16", "velodyne", "velodyne"),
    "vlp16-side": LidarModel("Velodyne VLP-16 on its side", "velodyne", "velodyne"),
}


def default_velodyne_dest(ip: str) -> tuple[str, int]:
    """Where an emulated VLP-16 on ``ip`` sends by default: port 2368 of 127.0.0.1 from
    a loopback address, else of 255.255.255.255 (the sensor's factory setting)."""
    return ("127.0.0.1" if ip.startswith("127.") else "255.255.255.255", fv.DATA_PORT)


def host_uri(model: LidarModel, device: object) -> str:
    """The URI a host on this machine opens ``device`` with: ``livox://IP`` and
    ``livox2://IP`` name the device, ``velodyne://IP:PORT`` where it sends to."""
    if isinstance(device, EmulatedVelodyne):
        ip, port = device.dest
        if ip == "255.255.255.255":  # a broadcast: listen on every interface
            return f"velodyne://{port}"
        return f"velodyne://{ip}:{port}"
    ip = device.address[0]  # type: ignore[attr-defined]
    return f"{model.scheme}://{ip}"


def lidar_device(
    sensor: SensorConfig | str,
    ip: str = "127.0.0.1",
    *,
    any_ports: bool = False,
    broadcast: bool = True,
    dest: tuple[str, int] | None = None,
) -> DeviceFactory:
    """The emulated device of a scenario's ``sensor`` on ``ip``: an SDK 1 device for the
    Avia and Mid-40 (command port 65000), the SDK 2 Mid-360 (ports 56000-56300), a
    VLP-16 sending to ``dest`` (``default_velodyne_dest`` if None) at the sensor's spin
    rate, its points turned into the head's frame for ``vlp16-side``.  ``any_ports``
    binds free ports instead (tests).  An SDK 1 device with ``broadcast`` announces
    itself to port 55000 of 127.0.0.1 if ``ip`` is a loopback address, else of
    255.255.255.255.  ConfigError for a sensor no device emulates."""
    cfg = SensorConfig(model=sensor) if isinstance(sensor, str) else sensor
    model = cfg.model
    if model not in DEVICES:
        known = ", ".join(DEVICES)
        raise ConfigError(f"emulate runs the sensors {known}; this scenario's sensor is {model!r}")
    protocol = DEVICES[model].protocol
    if protocol == "velodyne":
        to_host = dest if dest is not None else default_velodyne_dest(ip)
        rpm, rotation = spin_rpm(cfg), head_rotation(model)

        def vlp16(source: PointSource) -> StreamingDevice:
            return EmulatedVelodyne(source, ip=ip, dest=to_host, rpm=rpm, head_rotation=rotation)

        return vlp16
    if protocol == "livox-sdk2":

        def sdk2(source: PointSource) -> StreamingDevice:
            if any_ports:
                return EmulatedLivox2(
                    source, ip=ip, discovery_port=0, cmd_port=0, push_port=0, point_port=0
                )
            return EmulatedLivox2(source, ip=ip)

        return sdk2
    dev_type = AVIA if model == "avia" else MID40
    to = None
    if broadcast:
        to = ("127.0.0.1" if ip.startswith("127.") else "255.255.255.255", s1.BROADCAST_PORT)

    def sdk1(source: PointSource) -> StreamingDevice:
        port = 0 if any_ports else s1.LIDAR_CMD_PORT
        return EmulatedLivox(source, dev_type=dev_type, ip=ip, device_port=port, broadcast_to=to)

    return sdk1


livox_device = lidar_device  # its name before the VLP-16 came
