"""A Livox Viewer recording, ``.lvx`` or ``.lvx2`` (the bytes: ``formats.livox.lvx``), as a
recording.

Opening the file checks all of it before any frame is replayed: the headers, and the
chain of frames, each starting where the one before said the next would, numbered in
order, and filled exactly by its packages.  A file cut short or corrupt there gets one
``RecordingError`` naming the byte.  (A file cut exactly between two frames is whole
as far as the format can tell: it plays the frames before the cut.)  A malformed
packet inside a well-formed frame (an SDK 1 packet of the wrong version or timestamp
type, an LVX2 package of an unknown data type, a length of no whole points) is
skipped and counted in ``skipped["malformed_packets"]``, packages of a device the
header does not list in ``skipped["unknown_device"]``.

One device.  The pipeline follows one sensor, so a file of several LiDARs (a Mid-100,
a Livox Hub, several Mid-360s) replays the one ``--lidar-topic`` names: its broadcast
code or serial number, as ``dronetrack info`` lists them (``device N`` for one
without).

Sensor pose.  The points stay in the device's frame; every frame's pose is

    world_T_sensor = P · E

with E the device's extrinsics (``formats.livox.lvx``: R = Rz(yaw) Ry(pitch) Rx(roll), t =
x, y, z) when the file enables them, the identity otherwise, and P the
``--sensor-pose`` (the identity if not given: the extrinsics' frame is the world).
Without either, the sensor is taken as fixed at the origin, with a warning.

Times.  Every point has its own time, its packet's plus its firing's place in it.
Frames are cut by these times as a live stream's are (``sources.assembly``): frame k
holds the points of [t₀ + kT, t₀ + (k + 1)T), t₀ the device's first firing, with or
without a return, and T ``--period`` (0.1 s by default; the file's own 50 ms frames
are only how Livox Viewer stores the packets).  ``origin`` is t₀ on the device's clock:
Unix time when the device was synchronised (PTP, GPS), its time since power-up
otherwise.  A point older than the frame being filled (the clock went back) is
dropped and counted in ``skipped["late_points"]``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, RecordingError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.formats.livox.common import LivoxPoints
from dronetrack.formats.livox.lvx import (
    FRAME_HEADER,
    LVX2_INTERVAL_NS,
    LvxDevice,
    LvxHeader,
    Packages,
    decode_lvx1,
    decode_lvx2,
    header_bytes,
    parse_frame_header,
    parse_header,
    split_packages,
)
from dronetrack.sources.assembly import NS, PointBatch, StreamFrame, cut_by_time
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.livox.points import hits_in_time_order
from dronetrack.sources.livox.sdk1 import LINES
from dronetrack.sources.recordings.recording import (
    PointFileRecording,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    frame_period,
    identity_pose_warning,
    sensor_pose,
)
from dronetrack.types import Frame

__all__ = ["LvxFile", "LvxFrame", "LvxRecording"]

log = logging.getLogger(__name__)

MID360_LINES = 4  # a Mid-360 point's line: its index in the package mod 4 (sources.livox.sdk2)
_HEADER = FRAME_HEADER.itemsize


@dataclass(frozen=True)
class LvxFrame:
    """One frame of the file: its offset and size in the file (header included) and
    its packages (their offsets relative to the end of the frame's header)."""

    offset: int
    size: int
    packages: Packages


def topic_name(device: LvxDevice) -> str:
    """How ``info`` lists a device and ``--lidar-topic`` names it."""
    return device.code or f"device {device.ident}"


class LvxFile:
    """An LVX or LVX2 file, checked and indexed: its header and its frames' packages.
    RecordingError names what is wrong with a truncated or corrupt file."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise RecordingError(f"{self.path} does not exist or is not a file")
        self.size = self.path.stat().st_size
        with self.path.open("rb") as fh:
            try:
                self.header: LvxHeader = parse_header(fh.read(header_bytes(2, 255)))
            except DecodeError as err:
                raise RecordingError(
                    f"{self.path} is not a readable Livox LVX file: {err}"
                ) from None
            self.frames = self._index(fh)
        self.kind = "lvx" if self.header.major == 1 else "lvx2"

    def _problem(self, what: str, pos: int) -> RecordingError:
        return RecordingError(f"{self.path}: {what} (frame at byte {pos} of {self.size})")

    def _index(self, fh: BinaryIO) -> list[LvxFrame]:
        frames: list[LvxFrame] = []
        pos = self.header.data_offset
        fh.seek(pos)
        while pos < self.size:
            k = len(frames)
            raw = fh.read(_HEADER)
            if len(raw) < _HEADER:
                raise self._problem(f"truncated in the header of frame {k}", pos)
            cur, nxt, idx = parse_frame_header(raw)
            if cur != pos or idx != k or nxt < pos + _HEADER:
                raise self._problem(
                    f"corrupt frame header: frame {k} says it is frame {idx} at byte {cur}, "
                    f"the next one at byte {nxt}",
                    pos,
                )
            if nxt > self.size:
                raise self._problem(
                    f"truncated: frame {k} should end at byte {nxt}, after the end of the file "
                    f"(the {k} frames before it are whole)",
                    pos,
                )
            try:
                packages = split_packages(fh.read(nxt - pos - _HEADER), self.header.major)
            except DecodeError as err:
                raise self._problem(f"corrupt frame {k}: {err}", pos) from None
            frames.append(LvxFrame(pos, nxt - pos, packages))
            pos = nxt
        if not frames:
            raise RecordingError(f"{self.path} holds no frame after its header")
        return frames

    def body(self, fh: BinaryIO, frame: LvxFrame) -> bytes:
        """A frame's packages, read from the open file ``fh``."""
        fh.seek(frame.offset + _HEADER)
        return fh.read(frame.size - _HEADER)

    def decode(
        self, fh: BinaryIO, frame: LvxFrame, device: LvxDevice
    ) -> tuple[LivoxPoints, NDArray[np.uint8], int]:
        """``device``'s firings in ``frame`` (with or without a return), their lines and the
        number of malformed packets skipped."""
        packages = frame.packages.take(frame.packages.ident == device.ident)
        if len(packages) == 0:
            return LivoxPoints.empty(), np.zeros(0, np.uint8), 0
        body = self.body(fh, frame)
        if self.header.major == 1:
            interval = s1.POINT_INTERVAL_NS.get(device.device_type)
            lines = LINES.get(device.device_type, 1)
            return decode_lvx1(body, packages, interval, lines)
        interval = LVX2_INTERVAL_NS.get(device.device_type, LVX2_INTERVAL_NS[9])
        lines = MID360_LINES if device.device_type == 9 else 1
        return decode_lvx2(body, packages, interval, lines)

    def unknown_packages(self) -> int:
        """Packages whose device index or LiDAR ID no device info block has."""
        known = np.array([d.ident for d in self.header.devices], np.int64)
        return sum(int(np.count_nonzero(~np.isin(f.packages.ident, known))) for f in self.frames)

    def span_ns(self, device: LvxDevice | None = None) -> tuple[int, int] | None:
        """The first and last firing [ns] of ``device`` (every device if None), from the
        first and the last frame that decode to any; None if none does."""
        devices = self.header.devices if device is None else (device,)

        def firings(frame: LvxFrame, fh: BinaryIO) -> NDArray[np.int64]:
            parts = [self.decode(fh, frame, d)[0].t_ns for d in devices]
            return np.concatenate(parts)

        with self.path.open("rb") as fh:
            first = next((t for f in self.frames if len(t := firings(f, fh))), None)
            last = next((t for f in reversed(self.frames) if len(t := firings(f, fh))), None)
        if first is None or last is None:
            return None
        return int(first.min()), int(last.max())

    def info(self) -> RecordingInfo:
        """One topic per device, counting its packages; start and duration over all."""
        topics = []
        for d in self.header.devices:
            count = sum(int(np.count_nonzero(f.packages.ident == d.ident)) for f in self.frames)
            roll, pitch, yaw, x, y, z = d.extrinsic
            state = "on" if d.extrinsic_enabled else "off"
            kind = (
                f"{d.model} packets, extrinsics {state}: roll, pitch, yaw {roll:g}, {pitch:g}, "
                f"{yaw:g}°, x, y, z {x:g}, {y:g}, {z:g} m"
            )
            topics.append(TopicInfo(topic_name(d), kind, count))
        span = self.span_ns()
        start, end = span if span is not None else (0, 0)
        return RecordingInfo(self.path, self.kind, start / NS, (end - start) / NS, tuple(topics))


class LvxRecording(PointFileRecording):
    """One device of an LVX or LVX2 file, cut into frames by its points' times (see the
    module docstring)."""

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path)
        options = options or ReplayOptions()
        self.file = LvxFile(self.path)
        self.device = self._choose(options.lidar_topic)
        given = sensor_pose(options)
        self.pose = (np.eye(4) if given is None else given) @ self.device.pose
        if given is None and not self.device.extrinsic_enabled:
            self.pose_warning = identity_pose_warning(self.path)
        self.period = frame_period(options, None)
        mine = [f for f in self.file.frames if np.any(f.packages.ident == self.device.ident)]
        self._frames = mine
        span = self.file.span_ns(self.device) if mine else None
        if span is None:
            raise RecordingError(
                f"{self.path}: LiDAR {topic_name(self.device)!r} has no packet that decodes"
            )
        self.origin_ns, end_ns = span
        self.origin = self.origin_ns / NS
        period_ns = round(self.period * NS)
        self.n_frames = max(end_ns - self.origin_ns, 0) // period_ns + 1
        unknown = self.file.unknown_packages()
        if unknown:
            self.skipped["unknown_device"] += unknown
            log.warning("%s: %d packages of devices its header does not list", path, unknown)

    def _choose(self, topic: str | None) -> LvxDevice:
        devices = {topic_name(d): d for d in self.file.header.devices}
        if topic is not None:
            if topic not in devices:
                raise RecordingError(
                    f"{self.path} has no LiDAR {topic!r}; it has {', '.join(map(repr, devices))}"
                )
            return devices[topic]
        if len(devices) == 1:
            return next(iter(devices.values()))
        raise RecordingError(
            f"{self.path} holds {len(devices)} LiDARs ({', '.join(map(repr, devices))}) and the "
            "pipeline follows one: name it with --lidar-topic"
        )

    def __len__(self) -> int:
        return int(self.n_frames)

    def frames(self) -> Iterator[Frame]:
        """The frames in time order, each point at its own time."""
        name = self.path.name
        for done in cut_by_time(self._batches(), self.period, self.origin_ns, self.skipped, name):
            yield self._frame(done)

    def _batches(self) -> Iterator[PointBatch]:
        """The device's points, a batch for each frame of the file that holds any."""
        with self.path.open("rb") as fh:
            for lvx_frame in self._frames:
                pts, line, bad = self.file.decode(fh, lvx_frame, self.device)
                if bad:
                    self.skipped["malformed_packets"] += bad
                    log.warning("%s: skipped %d malformed packets", self.path.name, bad)
                if len(pts) == 0:
                    continue
                firings = (int(pts.t_ns.min()), int(pts.t_ns.max()))
                yield replace(hits_in_time_order([pts], [line]), firings=firings)

    def _frame(self, done: StreamFrame) -> Frame:
        pts = done.points
        return fixed_pose_frame(
            (done.start_ns - self.origin_ns) / NS,
            done.period_ns / NS,
            pts.xyz,
            t=(pts.t_ns - self.origin_ns) / NS,
            intensity=pts.reflectivity,
            line=pts.line,
            pose=self.pose,
        )

    def info(self) -> RecordingInfo:
        return self.file.info()
