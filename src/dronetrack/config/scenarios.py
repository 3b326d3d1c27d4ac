"""Named scenarios: the seeds' experiments, ready to run.

``default`` is seed 000's "horizontal fast" flight: a DJI Phantom 4 at up to
15 m/s out to about 140 m, seen by a Livox Avia on a WidowX turret in clear air.
"""

from __future__ import annotations

from pathlib import Path

from dronetrack.config.movers import VehicleConfig, WalkerConfig
from dronetrack.config.pipeline import (
    BackgroundConfig,
    ChooseConfig,
    FieldOfRegardConfig,
    PipelineConfig,
)
from dronetrack.config.presets import (
    AGGRESSIVE,
    FIELD,
    INDOOR,
    OUTDOOR,
    RELATIVE,
    RELATIVE_BASE_HEIGHT_M,
    STATIC_MID360,
)
from dronetrack.config.run import (
    ClutterConfig,
    DroneConfig,
    ObserverConfig,
    ScenarioConfig,
    SceneConfig,
    SensorConfig,
    TargetConfig,
    TrajectoryConfig,
    TurretConfig,
    WeatherConfig,
    load_scenario_file,
    with_rig_reach,
)
from dronetrack.errors import ScenarioError

__all__ = ["SCENARIOS", "get_scenario"]

# Seed 000's fog day: the Phantom 4 was tracked to 58 m.  With the Avia's
# rated-range law (γ = 0.276) Koschmieder extinction at this visibility puts the
# last returns from the drone near 60 m.
FOG_VISIBILITY_M = 100.0


def _scenario(
    name: str,
    description: str,
    duration: float,
    scene: str,
    drone: str,
    flight: str,
    sensor: str,
    turret: str,
    base_height: float,
    visibility: float = float("inf"),
    pipeline: PipelineConfig = OUTDOOR,
    observer: ObserverConfig | None = None,
) -> ScenarioConfig:
    scenario = ScenarioConfig(
        name=name,
        description=description,
        duration_s=duration,
        scene=SceneConfig(name=scene),
        drone=DroneConfig(model=drone),
        trajectory=TrajectoryConfig(name=flight),
        sensor=SensorConfig(model=sensor),
        turret=TurretConfig(model=turret, base_height_m=base_height),
        weather=WeatherConfig(visibility_m=visibility),
        observer=observer,
        pipeline=pipeline,
    )
    return with_rig_reach(scenario)


def _outdoor(
    name: str, flight: str, description: str, duration: float, visibility: float = float("inf")
) -> ScenarioConfig:
    """Seed 000 outdoors: Phantom 4, Avia on a WidowX on a 1 m stand."""
    return _scenario(
        name,
        description,
        duration,
        "outdoor",
        "phantom4",
        flight,
        "avia",
        "widowx",
        1.0,
        visibility,
    )


def _cluttered(
    base: ScenarioConfig, name: str, description: str, clutter: ClutterConfig
) -> ScenarioConfig:
    """``base`` with clutter in its scene."""
    scene = base.scene.model_copy(update={"clutter": clutter})
    return base.model_copy(update={"name": name, "description": description, "scene": scene})


# Clutter to measure false locks: the default amplitudes of sway (a moderate wind), a
# false alarm every 50 ms on average besides the sensor's own, and five birds, two of
# them sent across the line of sight to the drone, at 24 m (12 s after take-off, the
# drone 48 m out on its first pass) and at 54 m (40 s, the drone 108 m out).
OUTDOOR_CLUTTER = ClutterConfig(false_alarms_per_s=20.0, birds=5, bird_crossings_s=(12.0, 40.0))


def _indoor(
    name: str, flight: str, description: str, duration: float, scene: str = "indoor"
) -> ScenarioConfig:
    """Seed 000 indoors: Crazyflie, Avia on a WidowX whose base stood 0.55 m above the
    floor (LiVOX_MAV_track TF tree)."""
    return _scenario(
        name,
        description,
        duration,
        scene,
        "crazyflie2",
        flight,
        "avia",
        "widowx",
        0.55,
        pipeline=INDOOR,
    )


def _walk(name: str, flight: str, description: str, duration: float) -> ScenarioConfig:
    """Seed 003: a board carried by a walker, VLP-16 on a PTU-E46."""
    return _scenario(
        name, description, duration, "outdoor", "sign", flight, "vlp16", "ptu-e46", 1.0
    )


# The default site keeps a voxel as background only if a neighbour was hit in the scan
# too: a lone return is most often one of the sensor's random false alarms (a few hundred
# in the scan), which would hide a drone, or a bird, in its 4 m lookup cell for good.
# Over seeds 0-19: lock-on 97.6 → 98.5 % (worst seed 93.1 → 97.8 %), re-acquisitions
# over 1 s in 4 runs → 1.  Seed 000's own scenarios keep the reference's every-hit map.
_HORIZONTAL_FAST = _outdoor(
    "default",
    "horizontal-fast",
    "seed 000 horizontal fast: Phantom 4 at 15 m/s to 140 m, Avia on a WidowX, clear",
    66.0,
)
DEFAULT = _HORIZONTAL_FAST.model_copy(
    update={
        "pipeline": _HORIZONTAL_FAST.pipeline.model_copy(
            update={"background": BackgroundConfig(min_neighbours=1, near_track=True)}
        )
    }
)
# The acquisition scenarios watch a field of regard of ±90° pan, from 40° up to 5° down,
# out to 200 m: the background scan covers it and the crop box bounds it.
# A voxel needs two returns in the scan to be background: with one, the sensor's random
# false alarms mark about 1.5 % of the sky 10-30 m up as background (measured on the
# outdoor-incoming scan), and a drone hovering in such a cell vanishes from the foreground.
# Two hits need a longer scan of the wider field: 20 s, so the hedge is seen twice.
# Near the locked drone the points clearly in front of the scan's returns are kept
# (near_track): outdoor-hide's drone skimming the barn's corner stays in view (lock-on
# 94.2 → 97.8 %, seeds 0-4; the other scenarios' figures moved by 0.3 points at most).
OUTDOOR_FIELD = OUTDOOR.model_copy(
    update={
        "field_of_regard": FieldOfRegardConfig(
            pan_deg=(-90.0, 90.0), tilt_deg=(-40.0, 5.0), range_m=200.0
        ),
        "background": BackgroundConfig(min_hits=2, scan_s=20.0, near_track=True),
    }
)


def _acquisition(
    name: str, flight: str, description: str, duration: float, scene: str = "outdoor"
) -> ScenarioConfig:
    """Finding the drone by itself: seed 000's rig outdoors with a field of regard."""
    return _scenario(
        name,
        description,
        duration,
        scene,
        "phantom4",
        flight,
        "avia",
        "widowx",
        1.0,
        pipeline=OUTDOOR_FIELD,
    )


def _several(name: str, flights: list[str], description: str, duration: float) -> ScenarioConfig:
    """Several Phantom 4s in the acquisition rig's field of regard: the first flight is
    the target's (the one the run is scored on), the others ``[[targets]]`` entering as
    the background scan ends."""
    base = _acquisition(name, flights[0], description, duration)
    others = tuple(TargetConfig(model="phantom4", flight=f) for f in flights[1:])
    # the turret shares itself among the drones ([pipeline.choose], off by default)
    pipeline = base.pipeline.model_copy(update={"choose": ChooseConfig(enabled=True)})
    return base.model_copy(update={"targets": others, "pipeline": pipeline})


# outdoor-unscanned: the acquisition rig and its ±90° field of regard, but a background
# scan that holds the turret within ±5° of the home bearing, so (with the Avia's ±35°
# view) the map covers bearings within about ±40° only.  outdoor-masts' poles, masts, a
# cabinet and a shed's corner stand beyond 50° either side, behind the drone's path,
# and never enter the map; the drone waits off the sector (88°) during the scan.
UNSCANNED_PAN_DEG = (-5.0, 5.0)
_UNSCANNED = _acquisition(
    "outdoor-unscanned",
    "unscanned",
    "a background scan of the home bearing ±40° only; the drone comes in from 88°, and "
    "poles, masts, a cabinet and a shed's corner stand beyond it, off the scanned sector",
    50.0,
    scene="outdoor-masts",
)
UNSCANNED = _UNSCANNED.model_copy(
    update={
        "pipeline": _UNSCANNED.pipeline.model_copy(
            update={
                "background": BackgroundConfig(
                    min_hits=2, scan_s=10.0, near_track=True, scan_pan_deg=UNSCANNED_PAN_DEG
                )
            }
        )
    }
)

# site-busy: default's rig and map settings, with no clean scan: 1 s of it, the turret
# within ±5° of the home bearing and looking 10-15° up, at the drone already in the air
# 35 m out; four people walk 15-45 m out and a car drives in from beyond the view on the
# right and parks 34 m out, 20 s into the flight.
SITE_BUSY_WALKERS = (WalkerConfig(count=4, area_m=(15.0, -12.0, 45.0, 12.0)),)
SITE_BUSY_VEHICLES = (
    VehicleConfig(
        path_m=((90.0, -70.0), (50.0, -30.0), (30.0, -15.0)), arrive_s=20.0, speed_m_s=8.0
    ),
)
_SITE_BUSY = _scenario(
    "site-busy",
    "the drone in view from the first frame, no clean scan (1 s); four people walk below "
    "it 15-45 m out and a car drives in and parks 34 m out, 20 s into the flight",
    40.0,
    "outdoor",
    "phantom4",
    "site-roam",
    "avia",
    "widowx",
    1.0,
    pipeline=OUTDOOR.model_copy(
        update={
            "background": BackgroundConfig(
                min_neighbours=1,
                near_track=True,
                scan_s=1.0,
                scan_pan_deg=(-5.0, 5.0),
                scan_tilt_deg=(-15.0, -10.0),
            )
        }
    ),
)
SITE_BUSY = _SITE_BUSY.model_copy(
    update={"walkers": SITE_BUSY_WALKERS, "vehicles": SITE_BUSY_VEHICLES}
)

# mid360-static: a Mid-360 on a WidowX that never moves, set up as a site file would set
# up a real static Mid-360 (``STATIC_MID360``).  The drone hovers 2.0-2.9 m from it
# from the start; three people walk 3-14 m out, two in front of it and one behind.
MID360_STATIC_WALKERS = (
    WalkerConfig(count=2, area_m=(3.0, -8.0, 12.0, 8.0)),
    WalkerConfig(count=1, area_m=(-12.0, -8.0, -3.0, 8.0)),
)
_MID360_STATIC = _scenario(
    "mid360-static",
    "a static Mid-360 (no turret motion, 1 s scan, ±60 m crop, 0.5 m voxels); a Phantom 4 "
    "hovers 2.0-2.9 m from it from the start; three people walk 3-14 m out",
    30.0,
    "outdoor",
    "phantom4",
    "close-hover",
    "mid360",
    "widowx",
    1.0,
    pipeline=STATIC_MID360,
)
MID360_STATIC = _MID360_STATIC.model_copy(update={"walkers": MID360_STATIC_WALKERS})

_LIST = [
    DEFAULT,
    _acquisition(
        "outdoor-incoming",
        "incoming",
        "acquisition: the drone enters from beyond reach, 25° off the home bearing, at 15 m/s",
        40.0,
    ),
    _acquisition(
        "outdoor-enter",
        "enter",
        "acquisition: the drone enters the field of regard from the side, 70 m out, at 15 m/s",
        30.0,
    ),
    _acquisition(
        "outdoor-escape",
        "escape",
        "acquisition: away at 12 m/s beyond reach from 30 m out, back in on a bearing 40° round",
        65.0,
    ),
    _acquisition(
        "outdoor-hide",
        "hide",
        "acquisition: hides behind a barn at 60 m, reappears 25° further round, climbing",
        50.0,
        scene="outdoor-barn",
    ),
    _several(
        "outdoor-two-drones",
        ["crossing-left", "crossing-right"],
        "two Phantom 4s from 170 m out at bearings 60° apart (±30°), in to 110 m, across "
        "each other's path once (67 m out, 10 m apart in height) and away; scored on the "
        "first",
        35.0,
    ),
    _several(
        "outdoor-swarm",
        ["swarm-1", "swarm-2", "swarm-3", "swarm-4"],
        "four Phantom 4s 12-24 m apart flying together: in from 170 m out at 15° to 60 m, "
        "across to −45° and away; scored on the first",
        40.0,
    ),
    _cluttered(
        DEFAULT,
        "outdoor-clutter",
        "the default flight amid clutter: crowns swaying in a moderate wind, 20 false "
        "alarms/s, 5 birds, two crossing the line of sight at 12 s and 40 s",
        OUTDOOR_CLUTTER,
    ),
    UNSCANNED,
    SITE_BUSY,
    MID360_STATIC,
    _outdoor(
        "outdoor-simple-distance",
        "simple-distance",
        "seed 000 simple distance: straight out to 150 m and back",
        56.0,
    ),
    _outdoor(
        "outdoor-vertical", "vertical", "seed 000 vertical: a climbing line out to 150 m", 71.0
    ),
    _outdoor(
        "outdoor-horizontal-slow",
        "horizontal-slow",
        "seed 000 horizontal slow: 5 m/s passes out to 140 m",
        166.0,
    ),
    _outdoor(
        "outdoor-horizontal-fast",
        "horizontal-fast",
        "seed 000 horizontal fast: 15 m/s passes out to 140 m",
        66.0,
    ),
    _outdoor("field-sunny", "field", "seed 000 field test, sunny: 6 m/s out to 150 m", 66.0),
    _outdoor(
        "field-foggy",
        "field",
        f"seed 000 field test in fog: visibility {FOG_VISIBILITY_M:g} m",
        66.0,
        FOG_VISIBILITY_M,
    ),
    _indoor(
        "indoor-horizontal",
        "indoor-horizontal",
        "seed 000 indoor: Crazyflie, horizontal pattern",
        36.0,
    ),
    _indoor(
        "indoor-vertical", "indoor-vertical", "seed 000 indoor: Crazyflie, vertical pattern", 35.0
    ),
    _indoor("indoor-fast", "indoor-fast", "seed 000 indoor: Crazyflie, fast square pattern", 73.0),
    _indoor(
        "indoor-lost-and-found",
        "indoor-lost-and-found",
        "seed 000 indoor: Crazyflie hidden behind a partition and found again",
        86.0,
        scene="indoor-occluded",
    ),
    _walk("walk-line", "walk-line", "seed 003: a board walked towards a VLP-16 on a PTU-E46", 71.0),
    _walk("walk-across", "walk-across-7", "seed 003: a board walked across at 7 m", 91.0),
    _walk(
        "walk-square",
        "walk-square",
        "seed 003: a board walked in a square around the sensor",
        121.0,
    ),
    _scenario(
        "mid360-aggressive",
        "seed 002: F550 in random aggressive flight seen by a Mid-360",
        60.0,
        "outdoor",
        "f550",
        "aggressive",
        "mid360",
        "widowx",
        1.0,
        pipeline=AGGRESSIVE,
    ),
    _scenario(
        "seed003-field",
        "seed 003: a Spyder X4 flying laps to 33 m, a sideways VLP-16 sweeping on a PTU-E46",
        100.0,
        "outdoor",
        "spyder-x4",
        "seed003-field",
        "vlp16-side",
        "ptu-e46",
        1.0,
        pipeline=FIELD,
    ),
    _scenario(
        "seed002-relative",
        "seed 002: a Mid-360 on an F550 circling at 10 m tracks another F550 out to 55 m",
        60.0,
        "outdoor",
        "f550",
        "relative-out-and-back",
        "mid360",
        "widowx",
        RELATIVE_BASE_HEIGHT_M,
        pipeline=RELATIVE,
        observer=ObserverConfig(name="observer-orbit"),
    ),
]
SCENARIOS: dict[str, ScenarioConfig] = {s.name: s for s in _LIST}


def get_scenario(name_or_path: str) -> ScenarioConfig:
    """A named scenario, or one read from a ``.toml`` file."""
    if name_or_path in SCENARIOS:
        return SCENARIOS[name_or_path]
    path = Path(name_or_path).expanduser()
    if path.suffix.lower() == ".toml" or path.is_file():
        return load_scenario_file(path, SCENARIOS)
    raise ScenarioError(
        f"unknown scenario {name_or_path!r}; "
        "run 'dronetrack scenarios' to list them, or give a .toml file"
    )
