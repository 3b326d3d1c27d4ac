"""Pipeline presets of the named scenarios, after the reference implementation's
configurations and the seeds' rigs: ``OUTDOOR`` and ``INDOOR`` (seed 000's Avia
outside and in a room), ``AGGRESSIVE`` (a fast drone close in), ``RELATIVE`` (seed
002's Mid-360 riding on a drone), ``FIELD`` (seed 003's VLP-16 on a PTU) and
``STATIC_MID360`` (a Mid-360 standing still, set up as a site file would)."""

from __future__ import annotations

from dronetrack.config.pipeline import (
    BackgroundConfig,
    ControllerConfig,
    CropConfig,
    EvaluationConfig,
    PipelineConfig,
    TrackerConfig,
)
from dronetrack.config.rig import make_turret

__all__ = [
    "AGGRESSIVE",
    "FIELD",
    "INDOOR",
    "OUTDOOR",
    "RELATIVE",
    "RELATIVE_BASE_HEIGHT_M",
    "STATIC_MID360",
    "WIDOWX_MOUNT",
]

# Pipeline presets, after the reference implementation's configurations.
# mav_track_outside.yaml: 1 m voxels, 4 m lookup, eq. (11) at 15 m/s with seed 000's
# s_diag = 0.4 m for the Phantom 4.
OUTDOOR = PipelineConfig(tracker=TrackerConfig(s_diag=0.4))
INDOOR = PipelineConfig(
    # mav_track_inside.yaml: 0.1 m voxels looked up in 0.4 m cells; Crazyflie dynamics
    # (1.2 m/s, 1.2 m/s², 0.12 m) give σ_pos = σ_vel = 0.04, σ_m = 0.06 (seed 000 §III-E).
    crop=CropConfig(min_m=(1.0, -2.0, 0.0), max_m=(8.0, 2.0, 3.0)),
    background=BackgroundConfig(
        resolution_m=0.1, scan_pan_deg=(-40.0, 40.0), scan_tilt_deg=(-20.0, 10.0)
    ),
    tracker=TrackerConfig(
        v_max=1.2,
        a_max=1.2,
        s_diag=0.12,
        cylinder_center_m=(0.0, 0.0, 0.0),
        cylinder_radius_m=5.0,
        cylinder_height_m=2.0,
    ),
    controller=ControllerConfig(home_m=(3.0, 0.0, 1.2)),
    # A 4 m "correct" radius would cover most of the room: score within 0.3 m.
    evaluation=EvaluationConfig(correct_radius_m=0.3),
)
AGGRESSIVE = PipelineConfig(
    crop=CropConfig(min_m=(2.0, -15.0, 1.5), max_m=(30.0, 15.0, 15.0)),
    background=BackgroundConfig(
        resolution_m=0.5, scan_s=2.0, scan_pan_deg=(-10.0, 10.0), scan_tilt_deg=(0.0, 0.0)
    ),
    tracker=TrackerConfig(
        v_max=8.0,
        a_max=6.0,
        s_diag=0.55,
        cylinder_center_m=(15.0, 0.0, 2.0),
        cylinder_radius_m=10.0,
        cylinder_height_m=10.0,
    ),
    controller=ControllerConfig(home_m=(15.0, 0.0, 6.0)),
)
# Seed 002's relative tracking: the Mid-360 rides on an F550 (a fixed mount 0.1 m above
# its body), so there is no static background to learn: tracking starts at once.  The
# crop box is in the odometry (world) frame around the observer's orbit and the target's
# loop out to 55 m; its floor drops the ground.  The controller's home is a point in the
# observer's body frame: 20 m ahead, at the sensor's height, so the mount stays level.
RELATIVE_BASE_HEIGHT_M = 0.1
WIDOWX_MOUNT = make_turret("widowx").mount
_RELATIVE_SENSOR_Z = (
    RELATIVE_BASE_HEIGHT_M + WIDOWX_MOUNT.pan_to_tilt[2] + WIDOWX_MOUNT.tilt_to_sensor[2]
)
RELATIVE = PipelineConfig(
    crop=CropConfig(min_m=(-25.0, -35.0, 1.5), max_m=(80.0, 35.0, 30.0)),
    background=BackgroundConfig(enabled=False),
    tracker=TrackerConfig(
        v_max=9.0,
        a_max=7.0,
        s_diag=0.55,
        cylinder_center_m=(30.0, 0.0, 5.0),
        cylinder_radius_m=35.0,
        cylinder_height_m=15.0,
    ),
    controller=ControllerConfig(mode="fixed", home_m=(20.0, 0.0, _RELATIVE_SENSOR_Z)),
)

# Seed 003's field test: a VLP-16 on its side on a pan-only PTU-E46 sweeps ±90°; its
# filter node keeps the points in a box and then in a convex hull over the field,
# drawn clear of trees and lamps (here: above 5 m, 4-40 m out), with no background
# model.  The EKF (ekf-cv) is fed with cluster centroids.
_FIELD_HULL = tuple((x, y, z) for x in (4.0, 40.0) for y in (-25.0, 25.0) for z in (5.0, 25.0))
FIELD = PipelineConfig(
    crop=CropConfig(min_m=(-40.0, -40.0, 5.0), max_m=(40.0, 40.0, 25.0), hull_m=_FIELD_HULL),
    background=BackgroundConfig(enabled=False),
    tracker=TrackerConfig(kind="ekf-cv", v_max=4.0, a_max=2.0, s_diag=0.85),
    controller=ControllerConfig(mode="sweep", home_m=(20.0, 0.0, 10.0)),
)

# mid360-static's: a Mid-360 on a WidowX that never moves (the fixed mode at home, level,
# the scan held there), set up as a site file would set up a real static Mid-360: crop
# ±60 m about the sensor, 0.5 m voxels, a 1 s scan.
_STATIC_SENSOR_Z = 1.0 + WIDOWX_MOUNT.pan_to_tilt[2] + WIDOWX_MOUNT.tilt_to_sensor[2]
STATIC_MID360 = PipelineConfig(
    crop=CropConfig(min_m=(-60.0, -60.0, -60.0), max_m=(60.0, 60.0, 60.0)),
    background=BackgroundConfig(
        resolution_m=0.5, scan_s=1.0, scan_pan_deg=(0.0, 0.0), scan_tilt_deg=(0.0, 0.0)
    ),
    tracker=TrackerConfig(
        v_max=5.0,
        a_max=5.0,
        cylinder_center_m=(0.0, 0.0, 0.0),
        cylinder_radius_m=15.0,
        cylinder_height_m=10.0,
    ),
    controller=ControllerConfig(mode="fixed", home_m=(10.0, 0.0, _STATIC_SENSOR_Z)),
    # the drone is 2-3 m from people and the sensor: score within 1 m
    evaluation=EvaluationConfig(correct_radius_m=1.0),
)
