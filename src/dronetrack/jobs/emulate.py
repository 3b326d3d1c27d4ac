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

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dronetrack.config.rig import turret_spec
from dronetrack.config.run import ScenarioConfig
from dronetrack.formats.ptu import DEFAULT_BAUD
from dronetrack.jobs.factory import scan_duration
from dronetrack.jobs.run import run_seeds, turret_pipeline
from dronetrack.jobs.simulate import flight_config, resolve_run, start_angles
from dronetrack.sim.build import build_world
from dronetrack.sim.emulate.livox_stream import PointSource
from dronetrack.sim.emulate.rig import DeviceFactory, EmulatedRig, lidar_device
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import Frame

if TYPE_CHECKING:
    from dronetrack.sim.emulate.ros2 import Ros2Options

__all__ = ["TAIL_FRAMES", "TURRET_EMULATORS", "emulated_rig", "emulated_seconds"]

# Periods streamed past the scenario's end, so that a host closes its last frame (a
# frame is complete when a later point arrives).
TAIL_FRAMES = 2
# turret preset → the emulated device that drives it
TURRET_EMULATORS = {"widowx": "dynamixel", "ptu-e46": "ptu"}


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
