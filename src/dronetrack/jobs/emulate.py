"""``dronetrack emulate``'s rig: a scenario's simulator in real time behind an emulated
LiDAR (a Livox, or a VLP-16) and turret (``sim.emulate.rig``), on ``simulate``'s
timeline.  The turret is the preset's: two XM430 servos for the WidowX, a FLIR PTU for
the PTU-E46 (``TURRET_EMULATORS``).

The world is built as ``simulate`` builds it, from the same seed: the same flight,
starting after the background scan, and the turret at the same start pose.  Only its
integration time differs: it is stepped in the device's slices (about 20 ms), so
its returns are drawn differently, while the truth is the same path.
"""

from __future__ import annotations

import ipaddress
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dronetrack.config.rig import turret_spec
from dronetrack.config.run import ScenarioConfig
from dronetrack.errors import ConfigError, DeviceError, RunInterruptedError
from dronetrack.formats.ptu import BAUD_RATES, DEFAULT_BAUD
from dronetrack.interrupt import handling_sigterm, stop_requested, stoppable
from dronetrack.jobs.run import run_seeds, turret_pipeline
from dronetrack.jobs.simulate import flight_config, resolve_run, start_angles
from dronetrack.pipeline.factory import scan_duration
from dronetrack.realtime import frozen_heap
from dronetrack.sim.build import build_world
from dronetrack.sim.emulate.lidars import DEVICES, host_uri
from dronetrack.sim.emulate.livox_stream import PointSource
from dronetrack.sim.emulate.rig import DeviceFactory, EmulatedRig, lidar_device
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import Frame

if TYPE_CHECKING:
    from dronetrack.sim.emulate.ros2 import Ros2Options

__all__ = [
    "TAIL_FRAMES",
    "TURRET_EMULATORS",
    "EmulateOptions",
    "Emulation",
    "emulate_scenario",
    "emulated_rig",
    "emulated_seconds",
]

# Periods streamed past the scenario's end, so that a host closes its last frame (a
# frame is complete when a later point arrives).
TAIL_FRAMES = 2
# turret preset → the emulated device that drives it
TURRET_EMULATORS = {"widowx": "dynamixel", "ptu-e46": "ptu"}
POLL_S = 0.05  # how often the wait for the run's end looks at Ctrl-C, SIGTERM and the rig
LINGER_S = 2.0  # the devices answer this long after the stream, while the host closes
WAIT_S = 600.0  # how long it waits for a host by default
VELODYNE_PORT = 2368  # a VLP-16's data port by default


def emulated_seconds(cfg: ScenarioConfig) -> float:
    """Scenario time streamed: the background scan, the flight and the tail [s]."""
    tail = TAIL_FRAMES * cfg.sensor.integration_time_s
    return scan_duration(cfg.pipeline) + cfg.duration_s + tail


def emulated_rig(
    cfg: ScenarioConfig,
    *,
    lidar_ip: str = "127.0.0.1",
    serial_link: Path | None = None,
    truth: Path | None = None,
    any_ports: bool = False,
    lidar_dest: tuple[str, int] | None = None,
    warm_up: bool = True,
    on_slice: Callable[[Frame, FrameTruth], None] | None = None,
    ptu_baud: int = DEFAULT_BAUD,
    ros2: Ros2Options | None = None,
    ros_domain_id: int | None = None,
) -> EmulatedRig:
    """The rig of scenario ``cfg`` (resolved first), not yet started; a PTU-E46 turret
    is an emulated PTU on a line paced at ``ptu_baud``.

    ConfigError if the scenario's sensor is not one the emulator knows; DeviceError if
    the device's ports cannot be bound or the truth file written.  ``warm_up``
    compiles the simulator's kernels first, so the first slices are on time;
    ``any_ports``, ``lidar_dest`` (where a VLP-16 sends) and ``on_slice`` as
    ``lidar_device`` and ``EmulatedRig`` say.  With ``ros2``, the rig is on ROS 2
    domain ``ros_domain_id`` instead (``sim.emulate.ros2``: livox_ros_driver2's topic,
    /tf and the turret's topics; no UDP device, no pseudo-terminal; any sensor model).
    """
    cfg = resolve_run(cfg)
    spec = turret_spec(cfg.turret)
    make_device: DeviceFactory
    if ros2 is None:
        make_device = lidar_device(cfg.sensor, lidar_ip, any_ports=any_ports, dest=lidar_dest)
    else:
        from dronetrack.sim.emulate.ros2 import Ros2Device

        options, period, mount = ros2, cfg.sensor.integration_time_s, spec.mount

        def ros2_device(source: PointSource) -> Ros2Device:
            return Ros2Device(
                source, period_s=period, mount=mount, options=options, domain_id=ros_domain_id
            )

        make_device = ros2_device

    sim_seed, filter_seed = run_seeds(cfg.seed)
    flight = flight_config(cfg)
    # The pipeline only tells where simulate starts the turret.
    lead = turret_pipeline(
        cfg,
        cfg.sensor.integration_time_s,
        spec,
        np.random.default_rng(filter_seed),
    )
    mode = cfg.pipeline.controller.mode
    start: list[tuple[float, float] | None] = []

    def make_world(slice_s: float) -> SimWorld:
        sensor = flight.sensor.model_copy(update={"integration_time_s": slice_s})
        world = build_world(
            flight.model_copy(update={"sensor": sensor}), np.random.default_rng(sim_seed)
        )
        if not start:
            start.append(start_angles(world, lead, mode))
            if warm_up:
                world.warm_up()
        if start[0] is not None:
            world.place_turret(*start[0])
        return world

    rig = EmulatedRig(
        make_world,
        make_device,
        duration_s=emulated_seconds(cfg),
        serial_link=serial_link,
        truth=truth,
        on_slice=on_slice,
        ptu=spec if TURRET_EMULATORS.get(spec.name) == "ptu" else None,
        ptu_baud=ptu_baud,
        servos=ros2 is None,
    )
    attach = getattr(rig.device, "attach", None)
    if attach is not None:
        attach(rig)
    return rig


@dataclass(frozen=True, slots=True)
class EmulateOptions:
    """How ``dronetrack emulate`` serves a scenario: the LiDAR's address (and, for a
    VLP-16, where it sends), the turret's line, the truth file, or ROS 2 instead."""

    lidar_ip: str = "127.0.0.1"
    lidar_dest: str | None = None  # IP[:PORT], a VLP-16's destination
    serial_link: Path | None = None
    ptu_baud: int = DEFAULT_BAUD
    truth: Path | None = None
    ros2: bool = False
    ros_domain_id: int | None = None
    wait_s: float = WAIT_S
    pointcloud2: bool = False
    tf: bool = True

    def check(self) -> None:
        """ConfigError naming the first option that is wrong or goes with another rig."""
        try:
            ipaddress.IPv4Address(self.lidar_ip)
        except ValueError:
            raise ConfigError(f"--lidar-ip {self.lidar_ip!r} is not an IPv4 address") from None
        if self.ptu_baud not in BAUD_RATES:
            rates = ", ".join(map(str, BAUD_RATES))
            raise ConfigError(f"--ptu-baud {self.ptu_baud} is not a standard rate ({rates})")
        if not self.ros2 and (self.pointcloud2 or not self.tf or self.ros_domain_id is not None):
            raise ConfigError("--pointcloud2, --no-tf and --ros-domain-id go with --ros2")
        if self.ros2 and (self.serial_link is not None or self.lidar_dest is not None):
            raise ConfigError(
                "--serial-link and --lidar-dest are for the UDP rig; --ros2 has neither"
            )
        if self.lidar_dest is not None:
            destination(self.lidar_dest)

    def rig(self, cfg: ScenarioConfig) -> EmulatedRig:
        """The emulated rig of ``cfg`` these options describe, not yet started."""
        dest = None
        if self.lidar_dest is not None:
            known = DEVICES.get(cfg.sensor.model)
            if known is None or known.scheme != "velodyne":
                raise ConfigError(
                    "--lidar-dest is for a VLP-16; this scenario's LiDAR takes a host"
                )
            dest = destination(self.lidar_dest)
        ros2 = None
        if self.ros2:
            from dronetrack.sim.emulate.ros2 import Ros2Options

            ros2 = Ros2Options(pointcloud2=self.pointcloud2, tf=self.tf)
        return emulated_rig(
            cfg,
            lidar_ip=self.lidar_ip,
            serial_link=self.serial_link,
            truth=self.truth,
            lidar_dest=dest,
            ptu_baud=self.ptu_baud,
            ros2=ros2,
            ros_domain_id=self.ros_domain_id,
        )


def destination(text: str) -> tuple[str, int]:
    """``IP[:PORT]`` (port 2368 if not given); ConfigError naming the problem."""
    ip, colon, port = text.rpartition(":")
    if not colon:
        ip, port = text, str(VELODYNE_PORT)
    try:
        ipaddress.IPv4Address(ip)
    except ValueError:
        raise ConfigError(f"--lidar-dest {text!r}: {ip!r} is not an IPv4 address") from None
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"--lidar-dest {text!r}: {port!r} is not a UDP port in 1..65535")
    return ip, int(port)


@dataclass(frozen=True, slots=True)
class Emulation:
    """What an emulated run streamed: the scenario seconds, the messages or packets and
    the points sent, and the truth rows written."""

    streamed_s: float
    sent: int
    points: int
    truth_rows: int
    messages: str  # "point packets" or "point messages"


def addresses(cfg: ScenarioConfig, rig: EmulatedRig) -> tuple[list[str], str, str]:
    """The lines a host needs (the LiDAR's and the turret's URIs), what the rig waits
    for, and what it says when that came."""
    device = rig.device
    if rig.link is None:  # a ROS 2 rig: topics, no pseudo-terminal
        from dronetrack.sim.emulate.ros2 import Ros2Device

        assert isinstance(device, Ros2Device)
        o = device.options
        tf = "/tf and /tf_static" if o.tf else "no /tf"
        return (
            [
                f"lidar: ros2://{o.topic}  ({o.msg_type}, {o.frame_id}; {tf}; "
                f"ROS 2 domain {device.domain.domain_id})",
                f"turret: ros2://{o.turret_ns}  (sensor_msgs/JointState goals on "
                f"{o.command_topic}, states on {o.states_topic})",
            ],
            "a subscriber of " + o.topic,
            "a subscriber came",
        )
    model = DEVICES[cfg.sensor.model]
    ip, port = rig.address
    uri = host_uri(model, device)
    if model.scheme == "velodyne":
        wire = f"UDP from {ip}:{port} to {uri.removeprefix('velodyne://')}"
        waits, began = "a host to listen", "a host listens"
    else:
        wire = f"UDP {ip}:{port}"
        waits, began = "a host to start sampling", "sampling started"
    if rig.ptu is not None:
        what = f"FLIR PTU-E46, {rig.ptu_baud} baud 8N1"
    else:
        rate = "/".join(map(str, sorted(rig.bus.rates())))
        what = f"2 XM430-W350, pan ID 1, tilt ID 2, {rate} baud"
    lines = [
        f"lidar: {uri}  ({model.name}, {wire})",
        f"turret: {rig.turret_uri}  ({what}, on {rig.link.path})",
    ]
    return lines, waits, began


def serve(rig: EmulatedRig, began: str, wait_s: float, say: Callable[[str], None]) -> bool | None:
    """Let the rig serve hosts until its run is over: True once the scenario clock, from
    the last start, has passed the streamed length and the stream has ended (a host that
    stopped sampling ended it), and ``LINGER_S`` more have passed while the host closes
    (stops sampling, parks the turret); False on a stop request (Ctrl-C, SIGTERM); None
    if no host started the scenario within ``wait_s``.  Says each start."""
    ready = streaming = time.monotonic()
    announced = 0
    while not stop_requested():
        now = time.monotonic()
        if rig.starts > announced:
            announced = rig.starts
            say(f"{began}: the scenario clock runs")
        elapsed = rig.scenario_time(now)
        if rig.device.sampling:
            streaming = now
        if elapsed is None:
            if now - ready > wait_s:
                return None
        elif elapsed >= rig.duration_s + LINGER_S and now - streaming >= LINGER_S:
            return True
        time.sleep(POLL_S)
    return False


def emulate_scenario(
    cfg: ScenarioConfig,
    options: EmulateOptions,
    show: Callable[[str], None],
    say: Callable[[str], None],
) -> Emulation:
    """``dronetrack emulate``: build the rig, ``show`` its addresses, wait for a host and
    serve it until the scenario's stream is over.  DeviceError if no host came within
    ``options.wait_s``; RunInterruptedError (with what was sent) on Ctrl-C or SIGTERM."""
    options.check()
    rig = options.rig(cfg)
    # What is built stays: no full collection of it pauses a slice (measured 45 ms, once
    # about every 2 s of stream, without this; under 10 ms with it).
    with frozen_heap(), rig, handling_sigterm(), stoppable():
        lines, waits, began = addresses(cfg, rig)
        for line in lines:
            show(line)
        say(
            f"{cfg.name}: waiting for {waits}; then {scan_duration(cfg.pipeline):g} s of "
            f"background scan and {cfg.duration_s:g} s of flight "
            f"({emulated_seconds(cfg):g} s streamed)"
        )
        ended = serve(rig, began, options.wait_s, say)
        if ended is None:
            raise DeviceError(
                f"{cfg.name}: waited {options.wait_s:g} s for {waits}, none came (--wait-s)"
            )
    device = rig.device
    messages = "point messages" if options.ros2 else "point packets"
    done = Emulation(
        rig.slices * rig.slice_s, device.packets_sent, device.points_built, rig.truth_rows, messages
    )
    if not ended:
        kept = f"; truth ({done.truth_rows} rows) kept in {options.truth}" if options.truth else ""
        raise RunInterruptedError(f"{kept}; {done.sent} {messages} sent")
    return done
