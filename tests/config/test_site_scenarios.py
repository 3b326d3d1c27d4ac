"""The busy-site scenarios: outdoor-unscanned's structures stand off the scanned sector,
site-busy's drone is in view from the first frame amid walkers and a car, and
mid360-static's sensor never moves while the drone hovers 2-3 m from it and people walk
3-15 m out.  Each builds and runs a second or two of flight here; the whole runs are
the slow tests of ``tests/cli/test_site_scenarios.py``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dronetrack.config.scenarios import SCENARIOS
from dronetrack.geometry.transforms import FloatArray
from dronetrack.jobs.simulate import flight_config, run_simulation
from dronetrack.sim.build import build_world
from dronetrack.sim.scene import MASTS, MASTS_MIN_BEARING_DEG, SHED
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.site_flights import UNSCANNED_START
from dronetrack.sim.world import SimWorld
from dronetrack.types import Frame, Sample, StepResult, truth_objects

SHED_HALF_DIAGONAL_M = math.hypot(5.0, 4.0)  # the shed is 10 × 8 m


class Frames:
    """A sink that keeps every frame (the background scan's too) and its truth."""

    def __init__(self) -> None:
        self.frames: list[Frame] = []
        self.returns: list[np.ndarray] = []
        self.kinds: list[str] = []

    def write(self, sample: Sample, result: StepResult) -> None:
        objects = truth_objects(sample.truth)
        assert objects is not None
        self.frames.append(sample.frame)
        self.returns.append(objects.returns())
        self.kinds = objects.kinds.tolist()


def _short_run(name: str, seconds: float) -> Frames:
    cfg = SCENARIOS[name].model_copy(update={"duration_s": seconds})
    sink = Frames()
    run_simulation(cfg, sinks=[sink])
    return sink


def _avia_half_view_deg() -> float:
    """The widest azimuth of the Avia's pulses over 1 s, off its axis [deg]."""
    dirs = make_sensor("avia").pattern.pulses(0.0, 1.0).dirs
    return float(np.degrees(np.abs(np.arctan2(dirs[:, 1], dirs[:, 0])).max()))


def _structure_points(points: FloatArray) -> int:
    """How many world points lie on outdoor-masts' structures: within 1 m of a pole's or
    mast's axis (or the shed's footprint) and from 0.5 m above the ground to 0.5 m above
    its top."""
    count = 0
    for r, bearing, h in (*MASTS, SHED):
        b = math.radians(bearing)
        reach = SHED_HALF_DIAGONAL_M if (r, bearing, h) == SHED else 1.0
        near = np.hypot(points[:, 0] - r * math.cos(b), points[:, 1] - r * math.sin(b)) < reach
        count += int(np.count_nonzero(near & (points[:, 2] > 0.5) & (points[:, 2] < h + 0.5)))
    return count


def _structure_returns(world: SimWorld, pan_deg: float, tilt_deg: float, frames: int) -> int:
    world.place_turret(math.radians(pan_deg), math.radians(tilt_deg))
    return sum(_structure_points(world.step()[0].world_points()) for _ in range(frames))


def test_outdoor_unscanneds_structures_and_drone_stand_off_the_scanned_sector() -> None:
    cfg = SCENARIOS["outdoor-unscanned"]
    pan = cfg.pipeline.background.scan_pan_deg
    assert pan is not None
    sector = max(abs(p) for p in pan) + _avia_half_view_deg()
    # The scan sees bearings within about ±40°; the structures stand beyond 50° (the
    # widest, the shed, spans 2.2° each side of its centre 150 m out) and the drone
    # waits at 88° during the scan.
    assert sector < 41.0
    for r, bearing, _ in (*MASTS, SHED):
        assert abs(bearing) - math.degrees(SHED_HALF_DIAGONAL_M / r) > sector
    assert min(abs(b) for _, b, _ in (*MASTS, SHED)) >= MASTS_MIN_BEARING_DEG
    assert UNSCANNED_START[1] > sector
    assert cfg.scene.name == "outdoor-masts"
    assert cfg.pipeline.field_of_regard is not None
    assert cfg.pipeline.field_of_regard.pan_deg == (-90.0, 90.0)  # they are in the field


def test_outdoor_unscanneds_scan_never_returns_from_its_structures() -> None:
    """At the scan's extremes no return comes from a structure; turned towards them the
    sensor sees them (so the check can fail)."""
    cfg = SCENARIOS["outdoor-unscanned"]
    world = build_world(flight_config(cfg))
    pan = cfg.pipeline.background.scan_pan_deg
    assert pan is not None
    field = cfg.pipeline.field_of_regard
    assert field is not None
    for p in pan:
        for tilt in (*field.tilt_deg, -10.0):
            assert _structure_returns(world, p, tilt, 3) == 0
    assert _structure_returns(world, 60.0, -3.0, 3) > 50
    assert _structure_returns(world, -65.0, -3.0, 3) > 20


def test_site_busys_drone_is_in_view_from_the_first_frame_amid_walkers_and_a_car() -> None:
    cfg = SCENARIOS["site-busy"]
    assert cfg.pipeline.background.scan_s <= 1.0
    assert 3 <= sum(w.count for w in cfg.walkers) <= 6
    assert len(cfg.vehicles) == 1
    run = _short_run("site-busy", 1.0)
    assert run.kinds == ["drone", "walker", "walker", "walker", "walker", "vehicle"]
    returns = np.stack(run.returns)
    assert len(returns) == 20  # 1 s of scan, 1 s of flight
    assert returns[0, 0] > 0  # the drone, in the very first frame
    assert np.all(returns[:, 1:5].sum(axis=1) > 0)  # the walkers, in every frame
    # The car drives in during the flight, from beyond the view.
    movers = build_world(flight_config(cfg)).movers
    assert movers is not None
    assert 0.0 < movers.enter_s[-1] < cfg.pipeline.background.scan_s + cfg.vehicles[0].arrive_s


def test_mid360_statics_sensor_never_moves_and_sees_the_drone_from_the_first_frame() -> None:
    cfg = SCENARIOS["mid360-static"]
    pipeline = cfg.pipeline
    assert (cfg.sensor.model, pipeline.controller.mode) == ("mid360", "fixed")
    assert (pipeline.background.scan_s, pipeline.background.resolution_m) == (1.0, 0.5)
    assert pipeline.crop.min_m == (-60.0, -60.0, -60.0)
    assert pipeline.crop.max_m == (60.0, 60.0, 60.0)
    run = _short_run("mid360-static", 1.0)
    assert len(run.frames) == 20
    first = run.frames[0].poses[0]
    for frame in run.frames:
        np.testing.assert_array_equal(frame.poses, np.broadcast_to(first, frame.poses.shape))
    returns = np.stack(run.returns)
    assert np.all(returns[:, 0] > 0)  # the drone, 2-3 m away, in every frame


@pytest.mark.parametrize("seed", [0, 1])
def test_mid360_statics_drone_hovers_2_to_3_m_out_and_people_walk_3_to_15_m_out(
    seed: int,
) -> None:
    cfg = SCENARIOS["mid360-static"].model_copy(update={"seed": seed})
    world = build_world(flight_config(cfg))
    sensor = world.mount.base_vec + np.array([0.025, 0.0, 0.136])  # the WidowX level
    movers = world.movers
    assert movers is not None
    assert movers.kinds == ["walker"] * 3
    for t in np.arange(0.0, 1.0 + cfg.duration_s, 0.25):
        assert 2.0 <= np.linalg.norm(world.target_position(t) - sensor) <= 3.0
        away = np.hypot(*movers.positions(t)[:, :2].T)
        assert np.all((away >= 3.0) & (away <= 15.0))
