"""Write a simulated run as a Livox Viewer recording (``dronetrack record --format lvx``
or ``lvx2``; the bytes: ``formats.livox.lvx``).

An LVX file holds what Livox Viewer records: the LiDAR's point packets, and for each
device one fixed pose, its extrinsics.  It has no place for a turret's motion, the
ground truth or the scenario, so:

- the sensor must hold still (``--turret fixed``, no moving observer); its pose in
  the world goes into the extrinsics (enabled), and a frame with another pose is
  refused;
- the target's true position at every frame end is written beside the file as
  ``NAME.truth.csv`` (``t,x,y,z``; t in seconds after the recording's first firing,
  the start ``dronetrack info`` prints), and the resolved scenario as
  ``NAME.scenario.toml``: ``dronetrack track NAME.lvx --config NAME.scenario.toml
  --truth NAME.truth.csv`` replays the run as it was recorded.

Devices: the simulated Avia as an Avia (LVX, device type 7, data type 2: Cartesian,
one return, 96 firings a packet, 4.167 µs apart), the Mid-40 as a Mid-40 (LVX, type 1,
data type 0: 100 firings, 10 µs) and the Mid-360 as a Mid-360 (LVX2, type 9, data type
1: 96 points, 5 µs).  Each frame's firings lie on the device's grid from the frame's
start t₀: the point at time t, taken in time order, fires at

    k_i = max(round((t_i − t₀) / Δt), k_{i−1} + 1)

(a second point on a taken firing takes the next free one, so none is lost; the
simulated Avia fires every 4.1667 µs, a little faster than the device's 4.167 µs, so
a firing is shared about once in 12,500).  Every firing of the frame is written, those
without a point with zero range as a device sends them, in packets stamped with their
first firing's time, PTP-synchronised (timestamp type 1: t = 0 of the run is
``start_ns``).  The packets go into the file's 50 ms frames by that time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dronetrack.errors import ConfigError, InputError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.formats.livox.lvx import (
    FRAME_DURATION_MS,
    LVX2_INTERVAL_NS,
    LvxDevice,
    encode_frame,
    encode_header,
    encode_lvx2_packages,
    extrinsic_of,
)
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.recordings.recording import DEFAULT_PERIOD_S
from dronetrack.types import Frame, Sample, StepResult

__all__ = ["LVX_FORMATS", "LvxWriter", "lvx_turret_mode", "sidecar_paths"]

LVX_FORMATS = ("lvx", "lvx2")
DEFAULT_START_NS = 1_767_225_600 * 1_000_000_000  # as sinks.bag_writer: 2026-01-01 UTC
PTP = 1  # timestamp type: PTP-synchronised ns (SDK 1 and LVX2 alike)
POSE_TOL = 1e-9  # a frame's pose may differ from the first by this much (rounding)


@dataclass(frozen=True)
class _Device:
    major: int  # 1: LVX, 2: LVX2
    device_type: int
    data_type: int
    firings_per_packet: int
    interval_ns: int
    code: str


# simulated sensor → the device it is written as
DEVICES = {
    "avia": _Device(1, 7, 2, s1.POINTS_PER_PACKET[2], s1.POINT_INTERVAL_NS[7], "3GGDJ1234567890"),
    "mid40": _Device(1, 1, 0, s1.POINTS_PER_PACKET[0], s1.POINT_INTERVAL_NS[1], "0TFDG1234567890"),
    "mid360": _Device(2, 9, 1, 96, LVX2_INTERVAL_NS[9], "47MDK1234567890"),
}


def lvx_turret_mode(fmt: str, turret: str | None, compress: bool, livox_custom: bool) -> str:
    """The turret mode to record ``fmt`` with: "fixed", the only one an LVX file holds;
    ConfigError for another, or for the bag options ``compress`` and ``--pointcloud2``."""
    if compress:
        raise ConfigError("--compress applies to bags; an LVX file is written as Livox Viewer does")
    if not livox_custom:
        raise ConfigError("--pointcloud2 applies to bags; an LVX file holds the LiDAR's packets")
    if turret is not None and turret != "fixed":
        raise ConfigError(
            f"--format {fmt} holds one fixed sensor pose, so the turret holds still "
            f"(--turret fixed, the default for it), not --turret {turret}"
        )
    return "fixed"


def sidecar_paths(path: Path) -> tuple[Path, Path]:
    """Where the truth and the scenario of ``path`` go: NAME.truth.csv, NAME.scenario.toml."""
    return path.with_suffix(".truth.csv"), path.with_suffix(".scenario.toml")


def firing_slots(t: FloatArray, t0: float, interval_s: float) -> np.ndarray:
    """Firing indices of points at sorted times ``t`` [s] on a grid from ``t0``:
    k_i = max(round((t_i − t₀)/Δt), k_{i−1} + 1), vectorised as
    k_i = i + max_{j ≤ i}(r_j − j) with r the rounded indices."""
    i = np.arange(len(t), dtype=np.int64)
    raw = np.maximum(np.rint((np.asarray(t) - t0) / interval_s).astype(np.int64), 0)
    return np.maximum.accumulate(raw - i) + i if len(t) else i


class LvxWriter:
    """Streams a simulated run's frames into an LVX or LVX2 file, the truth and scenario
    beside it (module docstring); ``close`` finishes them.  ``sensor``: the simulated
    LiDAR's name; ``observer``: whether it rides on a moving observer (refused)."""

    def __init__(
        self,
        path: Path,
        fmt: str,
        sensor: str,
        config_text: str | None = None,
        observer: bool = False,
        *,
        start_ns: int = DEFAULT_START_NS,
    ) -> None:
        if fmt not in LVX_FORMATS:
            raise ConfigError(f"{fmt!r} is not an LVX format ({', '.join(LVX_FORMATS)})")
        if observer:
            raise ConfigError(
                f"--format {fmt} holds one fixed sensor pose, and this scenario's sensor rides "
                "on a moving observer; record it as a bag"
            )
        device = DEVICES.get(sensor)
        wanted = "avia or mid40" if fmt == "lvx" else "mid360"
        if device is None or device.major != LVX_FORMATS.index(fmt) + 1:
            raise ConfigError(
                f"--format {fmt} records a Livox Viewer {'1' if fmt == 'lvx' else '2'} LiDAR "
                f"(--sensor {wanted}), not {sensor!r}"
            )
        truth, scenario = sidecar_paths(path)
        for p in (path, truth, scenario):
            if p.exists():
                raise ConfigError(f"{p} exists; choose a new --out")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path, self.truth_path, self.scenario_path = path, truth, scenario
        self.format = fmt
        self.compression: str | None = None  # an LVX file is never compressed
        self.device = device
        self.start_ns = start_ns
        self.frames_written = 0
        self._fh = path.open("wb")
        self._pose: FloatArray | None = None
        self._t0: float | None = None  # the first frame's start [s]
        self._first_ns: int | None = None  # the file's first firing [ns]
        self._offset = 0
        self._bins: dict[int, list[bytes]] = {}
        self._truth: list[tuple[float, float, float, float]] = []
        self._udp = 0
        if config_text is not None:
            scenario.write_text(config_text)

    def write(self, sample: Sample, result: StepResult) -> None:
        """The run loop's sink: every frame, with the simulator's true target position."""
        truth = sample.truth
        if truth is None:
            raise InputError(
                "a recording is written from a simulated run: its frames need the truth"
            )
        self.frame(sample.frame, truth.target_position)

    def frame(self, frame: Frame, target: FloatArray) -> None:
        """Write one frame's packets (into the 50 ms frames they fall in) and the target's
        position at its end."""
        self._check_pose(frame)
        if self._t0 is None:
            self._t0 = frame.stamp
        d = self.device
        dt = d.interval_ns * 1e-9
        order = np.argsort(frame.t, kind="stable")
        slots = firing_slots(frame.t[order], frame.stamp, dt)
        n = d.firings_per_packet
        firings = max(
            math.ceil(frame.duration / dt - 1e-9), int(slots[-1]) + 1 if len(slots) else 0
        )
        packets = max(-(-firings // n), 1)
        xyz = np.zeros((packets * n, 3))
        refl = np.zeros(packets * n, np.uint8)
        xyz[slots] = frame.points[order]
        refl[slots] = np.clip(np.rint(frame.intensity[order]), 0, 255).astype(np.uint8)
        t0_ns = self.start_ns + round(frame.stamp * 1e9)
        if d.major == 1:
            raw = s1.encode_point_packets(
                xyz,
                refl,
                data_type=d.data_type,
                t0_ns=t0_ns,
                point_interval_ns=d.interval_ns,
                timestamp_type=PTP,
            )
            packages = [b"\0" + p for p in raw]  # device index 0
        else:
            packages = encode_lvx2_packages(
                xyz,
                refl,
                lidar_id=0,
                t0_ns=t0_ns,
                point_interval_ns=d.interval_ns,
                data_type=d.data_type,
                points_per_package=n,
                timestamp_type=PTP,
                udp_counter=self._udp,
            )
            self._udp = (self._udp + len(packages)) & 0xFFFF
        if self._first_ns is None:
            self._first_ns = t0_ns
        stamps = t0_ns + np.arange(packets, dtype=np.int64) * (n * d.interval_ns)
        bins = (stamps - self._first_ns) // (FRAME_DURATION_MS * 1_000_000)
        for b, package in zip(bins.tolist(), packages, strict=True):
            self._bins.setdefault(b, []).append(package)
        self._flush(below=int(bins[0]))
        x, y, z = (float(v) for v in target)
        self._truth.append((frame.end - self._t0, x, y, z))

    def _check_pose(self, frame: Frame) -> None:
        if self._pose is None:
            self._pose = np.asarray(frame.poses[0], np.float64)
            self._write_header(self._pose)
        elif not np.allclose(frame.poses, self._pose, rtol=0.0, atol=POSE_TOL):
            raise InputError(
                f"the sensor moved at t = {frame.stamp:.3f} s, and an LVX file holds one fixed "
                "pose per LiDAR: record with --turret fixed"
            )

    def _write_header(self, pose: FloatArray) -> None:
        d = self.device
        info = LvxDevice(
            code=d.code,
            hub_code="",
            ident=0,
            device_type=d.device_type,
            extrinsic_enabled=True,
            extrinsic=extrinsic_of(pose),
            lidar_type=247 if d.major == 2 else 0,  # as Livox Viewer 2's own files have it
        )
        head = encode_header(d.major, [info])
        self._fh.write(head)
        self._offset = len(head)

    def _flush(self, below: int | None = None) -> None:
        """Write the 50 ms frames of the bins before ``below`` (all if None)."""
        for b in sorted(self._bins):
            if below is not None and b >= below:
                break
            data = encode_frame(self._offset, self.frames_written, b"".join(self._bins.pop(b)))
            self._fh.write(data)
            self._offset += len(data)
            self.frames_written += 1

    def replay_hint(self, period_s: float) -> str:
        """Where the truth and scenario went, and the command that replays the run with them
        (``--period`` if the frames were not the replay's default 0.1 s)."""
        cmd = (
            f"dronetrack track {self.path} --config {self.scenario_path} --truth {self.truth_path}"
        )
        if period_s != DEFAULT_PERIOD_S:
            cmd += f" --period {period_s:g}"
        return f"truth {self.truth_path}, scenario {self.scenario_path}; replay with `{cmd}`"

    def close(self) -> None:
        """Write the frames still held, the truth file, and close."""
        if self._fh.closed:
            return
        self._flush()
        self._fh.close()
        rows = "".join(f"{t:.9f},{x!r},{y!r},{z!r}\n" for t, x, y, z in self._truth)
        self.truth_path.write_text("t,x,y,z\n" + rows)
