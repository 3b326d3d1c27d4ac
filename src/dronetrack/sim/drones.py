"""Targets built from simple shapes in their body frame (x forward, y left, z up).

Sizes follow sensor_physics.md §5.  No measured 905 nm reflectivity of any of
these airframes was found (§3.4): the values are assumptions by material (white
plastic shell high, carbon and PCB low, spinning propellers a thin average), and
the Phantom 4 shell is set so that an Avia on a turret sees it out to about
140 m in clear air, the reach seed 000 reports.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dronetrack.config.rig import TARGETS
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray, unit
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.shapes import box, cylinder, oriented

__all__ = ["DRONE_NAMES", "DroneModel", "attitude_from_acceleration", "make_drone"]

GRAVITY = 9.81  # [m/s²]


@dataclass(frozen=True, slots=True)
class DroneModel:
    """A target: its shapes in the body frame and its dynamics envelope."""

    name: str
    s_diag: float  # motor-to-motor diagonal [m]
    v_max: float  # [m/s]
    a_max: float  # [m/s²]
    body: Primitives
    faces_sensor: bool = False  # turn body +x towards the turret base (a hand-held board)

    @property
    def radius(self) -> float:
        """Radius of a sphere about the body origin that holds every part [m]."""
        return float(np.max(np.linalg.norm(self.body.center, axis=1) + self.body.bound_radius))


def attitude_from_acceleration(acceleration: FloatArray, yaw: float = 0.0) -> FloatArray:
    """world_R_body of a multirotor: thrust (body z) along a + g ẑ, body x at ``yaw``.

    z_b = (a + g ẑ) / |a + g ẑ|;  x_b = unit(x_yaw − (x_yaw·z_b) z_b);  y_b = z_b × x_b
    """
    z_b = unit(np.asarray(acceleration, dtype=np.float64) + np.array([0.0, 0.0, GRAVITY]))
    x_yaw = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    x_b = unit(x_yaw - np.dot(x_yaw, z_b) * z_b)
    y_b = np.cross(z_b, x_b)
    return np.column_stack([x_b, y_b, z_b])


def _multirotor(
    n_arms: int,
    s_diag: float,
    body_size: tuple[float, float, float],
    arm_width: float,
    motor_radius: float,
    prop_radius: float,
    rho_body: float,
    rho_arm: float,
    rho_motor: float,
    rho_prop: float,
    legs: tuple[float, float] | None = None,
    rho_legs: float = 0.5,
) -> Primitives:
    """Body box, arms to the motors, motor cans, propeller discs and landing legs."""
    parts = [box((0.0, 0.0, 0.0), body_size, rho_body)]
    arm_len = 0.5 * s_diag
    for k in range(n_arms):
        yaw = np.pi / n_arms + 2.0 * np.pi * k / n_arms
        c, s = np.cos(yaw), np.sin(yaw)
        parts.append(
            box(
                (0.5 * arm_len * c, 0.5 * arm_len * s, 0.0),
                (arm_len, arm_width, arm_width),
                rho_arm,
                yaw=yaw,
            )
        )
        motor = (arm_len * c, arm_len * s, 0.5 * arm_width + motor_radius)
        parts.append(cylinder(motor, motor_radius, 2.0 * motor_radius, rho_motor))
        # A spinning propeller is a thin disc whose reflectivity is the blade
        # fill (~10 % of the disc) times the blade plastic's reflectivity.
        prop = (motor[0], motor[1], motor[2] + motor_radius + 0.005)
        parts.append(cylinder(prop, prop_radius, 0.01, rho_prop))
    if legs is not None:
        height, spread = legs
        for side in (-1.0, 1.0):
            z = -0.5 * body_size[2] - 0.5 * height
            # Two struts per side and a skid along x.
            for fwd in (-1.0, 1.0):
                parts.append(
                    cylinder((0.35 * spread * fwd, side * 0.5 * spread, z), 0.006, height, rho_legs)
                )
            skid_z = -0.5 * body_size[2] - height
            parts.append(
                cylinder(
                    (0.0, side * 0.5 * spread, skid_z),
                    0.006,
                    spread,
                    rho_legs,
                    rotation=oriented(pitch=np.pi / 2),
                )
            )
    return Primitives.concat(parts)


def _model(name: str, body: Primitives, faces_sensor: bool = False) -> DroneModel:
    """The target preset ``name`` (size and dynamics, ``config.rig``) with this body."""
    spec = TARGETS[name]
    return DroneModel(name, spec.s_diag, spec.v_max, spec.a_max, body, faces_sensor)


def _phantom4() -> DroneModel:
    # 350 mm diagonal, 24 cm propellers, white glossy shell with landing legs.  A
    # glossy curved shell sends much of the light away from the sensor: its
    # effective diffuse reflectivity (0.22) is set so that an Avia on a turret
    # sees the drone in half of its frames at 140 m and in one in ten at 160 m,
    # matching seed 000's last returns at 135-147 m and its 130 m tracking range.
    body = _multirotor(
        4,
        TARGETS["phantom4"].s_diag,
        (0.20, 0.14, 0.09),
        0.035,
        0.016,
        0.12,
        rho_body=0.22,
        rho_arm=0.22,
        rho_motor=0.04,
        rho_prop=0.02,
        legs=(0.10, 0.20),
        rho_legs=0.22,
    )
    camera = box((0.06, 0.0, -0.07), (0.05, 0.05, 0.05), 0.06)
    return _model("phantom4", body=Primitives.concat([body, camera]))


def _crazyflie2() -> DroneModel:
    # 92 mm motor-to-motor (s_diag 12 cm in seed 000), PCB and battery, 45 mm propellers.
    body = _multirotor(
        4,
        TARGETS["crazyflie2"].s_diag,
        (0.05, 0.05, 0.012),
        0.006,
        0.0035,
        0.0225,
        rho_body=0.15,
        rho_arm=0.10,
        rho_motor=0.20,
        rho_prop=0.03,
    )
    return _model("crazyflie2", body=body)


def _f550() -> DroneModel:
    # DJI F550 hexacopter: 550 mm wheelbase, plastic arms, 10" propellers.
    body = _multirotor(
        6,
        TARGETS["f550"].s_diag,
        (0.18, 0.18, 0.06),
        0.04,
        0.014,
        0.127,
        rho_body=0.25,
        rho_arm=0.30,
        rho_motor=0.10,
        rho_prop=0.04,
        legs=(0.15, 0.25),
        rho_legs=0.3,
    )
    return _model("f550", body=body)


def _spyder_x4() -> DroneModel:
    # Sky Hero Spyder X4: 0.85 m carbon quadrotor, 15" propellers.
    body = _multirotor(
        4,
        TARGETS["spyder-x4"].s_diag,
        (0.24, 0.20, 0.10),
        0.03,
        0.02,
        0.19,
        rho_body=0.12,
        rho_arm=0.08,
        rho_motor=0.10,
        rho_prop=0.03,
        legs=(0.20, 0.35),
        rho_legs=0.1,
    )
    return _model("spyder-x4", body=body)


def _sign() -> DroneModel:
    # The board a walker holds up in seed 003's walks: 0.6 × 0.45 m, facing ±x.
    board = box((0.0, 0.0, 0.0), (0.01, 0.60, 0.45), 0.5)
    return _model("sign", body=board, faces_sensor=True)


_BUILDERS = {
    "phantom4": _phantom4,
    "crazyflie2": _crazyflie2,
    "f550": _f550,
    "spyder-x4": _spyder_x4,
    "sign": _sign,
}
DRONE_NAMES = tuple(_BUILDERS)
assert set(DRONE_NAMES) == set(TARGETS), "a body for every target preset"


def make_drone(name: str, reflectivity_scale: float = 1.0) -> DroneModel:
    """A target by name, with every part's reflectivity scaled by ``reflectivity_scale``."""
    key = name.strip().lower()
    if key not in _BUILDERS:
        raise ConfigError(f"unknown drone {name!r}; choose one of {', '.join(DRONE_NAMES)}")
    if not reflectivity_scale > 0:
        raise ConfigError(f"drone reflectivity scale must be positive, got {reflectivity_scale}")
    model = _BUILDERS[key]()
    if reflectivity_scale == 1.0:
        return model
    body = model.body
    scaled = Primitives(
        body.kind,
        body.center,
        body.rotation,
        body.half,
        np.clip(body.reflectivity * reflectivity_scale, 0.0, 1.0),
    )
    return replace(model, body=scaled)
