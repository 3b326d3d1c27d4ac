"""LiDAR sensor models: scan pattern plus the datasheet physics.

Numbers from the team's research notes (shared/research/sensor_physics.md);
[A] marks an assumption where no source gave a value.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.rig import SENSOR_MODELS
from dronetrack.errors import SensorError
from dronetrack.sim.mounted import RotatedPattern, side_mount
from dronetrack.sim.patterns import (
    MID360_PATTERN,
    ScanPattern,
    TablePattern,
    avia_pattern,
    load_pattern_table,
    mid40_pattern,
    vlp16_pattern,
)

__all__ = ["SENSOR_NAMES", "SensorModel", "make_sensor"]


@dataclass(frozen=True, slots=True)
class SensorModel:
    """A LiDAR: its scan pattern, rated range, beam and noise (SI units, radians)."""

    name: str
    pattern: ScanPattern
    rated_range_m: float  # range at which a beam-filling target of rated_reflectivity has P_d = ½
    rated_reflectivity: float
    gamma: float  # rated-range exponent, R_max ∝ ρ^γ
    divergence_h: float  # full beam divergence across the horizontal axis [rad]
    divergence_v: float  # and the vertical axis [rad]
    range_sigma_m: float
    angular_sigma: float  # [rad], 1σ per axis
    min_range_m: float
    max_range_m: float
    false_alarm_rate: float  # spurious returns per pulse
    pd_width_db: float = 1.0  # [A] logistic width of P_d
    beam_samples: int = 32  # sub-rays across the footprint for small targets

    def with_noise(self, enabled: bool) -> SensorModel:
        """The same sensor with range/angle noise and false alarms on or off."""
        if enabled:
            return self
        return replace(self, range_sigma_m=0.0, angular_sigma=0.0, false_alarm_rate=0.0)


def _livox(
    name: str,
    pattern: ScanPattern,
    rated_range_m: float,
    gamma: float,
    angular_sigma_deg: float,
    min_range_m: float,
    max_range_m: float,
) -> SensorModel:
    """A Livox sensor: rated at 10 % reflectivity, 0.03° (H) × 0.28° (V) beam, 2 cm range noise,
    false alarms below 0.01 % (taken at that bound)."""
    return SensorModel(
        name=name,
        pattern=pattern,
        rated_range_m=rated_range_m,
        rated_reflectivity=0.10,
        gamma=gamma,
        divergence_h=np.radians(0.03),
        divergence_v=np.radians(0.28),
        range_sigma_m=0.02,
        angular_sigma=np.radians(angular_sigma_deg),
        min_range_m=min_range_m,
        max_range_m=max_range_m,
        false_alarm_rate=1e-4,
    )


def _avia() -> SensorModel:
    # Rated 190 m at 10 % (100 klx); γ = 0.276 fits 190 m @ 10 % against 230 m @ 20 %.
    return _livox("avia", avia_pattern(), 190.0, 0.276, 0.05, 1.0, 450.0)


def _mid40() -> SensorModel:
    # Rated 90 m at 10 %, 130 m at 20 %: γ ≈ 0.53, taken as the fixed-threshold ½.
    return _livox("mid40", mid40_pattern(), 90.0, 0.5, 0.1, 1.0, 260.0)


def _mid360() -> SensorModel:
    # Rated 40 m at 10 %, 70 m at 80 %: γ = 0.269.  Its divergence is not published;
    # the other Livox sensors' 0.03° × 0.28° is assumed [A].
    return _livox("mid360", MID360_PATTERN, 40.0, 0.269, 0.15, 0.1, 70.0)


def _vlp16(rpm: float = 600.0) -> SensorModel:
    # 100 m maximum range.  The datasheet gives no reflectivity for it; rating it
    # at 80 % [A] puts the reach on a 0.45 m drone near the 70 m Dogru & Marques
    # report.  Divergence 3.0 × 1.5 mrad (VLS-128 manual, RGL constants).
    return SensorModel(
        name="vlp16",
        pattern=vlp16_pattern(rpm),
        rated_range_m=100.0,
        rated_reflectivity=0.80,
        gamma=0.5,
        divergence_h=3.0e-3,
        divergence_v=1.5e-3,
        range_sigma_m=0.02,  # the datasheet's "±3 cm typical" read as about 1.5 σ
        angular_sigma=np.radians(0.05),  # [A]
        min_range_m=0.5,
        max_range_m=100.0,
        false_alarm_rate=1e-5,  # [A]
        beam_samples=16,
    )


def _vlp16_side(rpm: float = 600.0) -> SensorModel:
    # Seed 003's mounting: the VLP-16 on its side on the PTU-E46, rolled 90° about its
    # forward axis (sim/mounted.py).  The spin sweeps elevation and the 16 beams fan out
    # ±15° in azimuth, 2° apart.  The footprint turns with the head: its 3.0 mrad along
    # the spin now lies in the vertical, its 1.5 mrad across the beams in the horizontal
    # (the simulator's footprint axes are the sensor's horizontal and vertical).
    upright = _vlp16(rpm)
    return replace(
        upright,
        name="vlp16-side",
        pattern=RotatedPattern(upright.pattern, side_mount()),
        divergence_h=upright.divergence_v,
        divergence_v=upright.divergence_h,
    )


# Spinning heads, whose spin rate (rpm) can be set.
_SPINNING: dict[str, Callable[[float], SensorModel]] = {
    "vlp16": _vlp16,
    "vlp16-side": _vlp16_side,
}
_BUILDERS: dict[str, Callable[[], SensorModel]] = {
    "avia": _avia,
    "mid40": _mid40,
    "mid360": _mid360,
    "vlp16": _vlp16,
    "vlp16-side": _vlp16_side,
}
SENSOR_NAMES = (*_BUILDERS, "file:PATH")
assert tuple(_BUILDERS) == SENSOR_MODELS, "a model for every sensor name"


def make_sensor(
    name: str,
    *,
    noise: bool = True,
    rpm: float | None = None,
    rate_hz: float | None = None,
    lines: int | None = None,
    physics: str | None = None,
    **overrides: Any,
) -> SensorModel:
    """Build a sensor by name: one of ``SENSOR_NAMES``.

    ``vlp16-side`` is the VLP-16 lying on its side (seed 003): its spin sweeps
    elevation and its beams fan out in azimuth.  ``file:PATH`` replays a
    scan-pattern table (Livox CSV or (N, 2) .npy) at ``rate_hz`` (default
    240,000 points/s) over ``lines`` lines, with the physics of the sensor named
    by ``physics`` (default ``avia``).  ``rpm`` sets a VLP-16's spin rate, upright
    or on its side.  Other keyword arguments replace fields of the model (for
    example ``range_sigma_m``).
    """
    key = name.strip()
    lowered = key.lower()
    is_file = lowered.startswith("file:")
    if not is_file and lowered not in _BUILDERS:
        raise SensorError(f"unknown sensor {name!r}; choose one of {', '.join(SENSOR_NAMES)}")
    if rpm is not None and lowered not in _SPINNING:
        raise SensorError(
            f"a spin rate (rpm) applies to vlp16 only ({', '.join(_SPINNING)}), not to {name!r}"
        )
    if not is_file and (rate_hz is not None or lines is not None or physics is not None):
        raise SensorError(
            f"point rate, line count and physics apply to file: patterns, not {name!r}"
        )
    if is_file:
        path = Path(key[5:]).expanduser()
        physics = physics or "avia"
        if physics not in _BUILDERS:
            raise SensorError(
                f"unknown sensor physics {physics!r}; choose one of {', '.join(_BUILDERS)}"
            )
        az, el = load_pattern_table(path)
        pattern = TablePattern(az, el, rate_hz=rate_hz or 240_000.0, n_lines=lines or 1)
        model = replace(_BUILDERS[physics](), name=f"file:{path}", pattern=pattern)
    else:
        model = _SPINNING[lowered](rpm) if rpm is not None else _BUILDERS[lowered]()
    if overrides:
        unknown = set(overrides) - set(SensorModel.__dataclass_fields__)
        if unknown:
            raise SensorError(f"unknown sensor parameter(s): {', '.join(sorted(unknown))}")
        model = replace(model, **overrides)
    return model.with_noise(noise)
