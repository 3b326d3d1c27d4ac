"""The live source on loopback: the emulated Avia streams a known grid, the Livox
client decodes it, and ``LiveSource`` cuts it into frames by the points' times, drops
whole frames when its consumer falls behind, ends on a silent device, and gives the
run loop what it needs to measure the latency.

Every wait is bounded: the grid lasts 2 s at most, and each test stops by itself."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.pipeline import run
from dronetrack.sim.emulate.livox import EmulatedLivox, GridSource, grid_points
from dronetrack.sim.emulate.livox_stream import PointChunk
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.live import LiveSource
from dronetrack.sources.livox.sdk1 import LivoxClient, LivoxEndpoint
from dronetrack.types import Frame, Sample, StepResult, TurretCommand, TurretState

LOOP = "127.0.0.1"
DT = 4_167  # ns between an Avia's firings
STRIDE = 10  # every 10th firing holds a point: 24,000 points/s


@contextmanager
def avia(duration_s: float, **client_kw: object) -> Iterator[tuple[LivoxClient, EmulatedLivox]]:
    """An emulated Avia streaming the grid for ``duration_s``, and an open client."""
    dev = EmulatedLivox(GridSource(DT, duration_s, stride=STRIDE), device_port=0)
    ep = LivoxEndpoint(LOOP, None, 0, 0, 0, dev.address[1])
    client = LivoxClient(ep, discover_s=0.0, **client_kw)  # type: ignore[arg-type]
    try:
        dev.start()
        client.open(timeout_s=2.0)
        yield client, dev
    finally:
        client.close()
        dev.close()


def test_frames_are_cut_by_the_points_times_with_the_turrets_pose() -> None:
    """Each frame holds exactly the grid's points of its 100 ms, on the run's clock
    (seconds since the first point); a fixed sensor's pose is the mount's."""
    with avia(1.0) as (client, _):
        source = LiveSource(client, MountGeometry(), period_s=0.1, duration_s=0.5)
        samples = list(source)
    assert [round(s.frame.stamp, 9) for s in samples] == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])
    for s in samples:
        f = s.frame
        # the firings k = 10 j whose time k Δt falls in [stamp, stamp + T)
        k = np.arange(0, 10**6, STRIDE)
        t = k * DT * 1e-9
        k = k[(t >= f.stamp - 1e-12) & (t < f.end - 1e-12)]
        np.testing.assert_allclose(f.t, k * DT * 1e-9, atol=1e-12)
        np.testing.assert_allclose(f.points, grid_points(k), atol=1e-9)
        assert s.received is not None
        assert s.turret is not None
        assert s.turret.pan == s.turret.tilt == 0.0
        np.testing.assert_allclose(f.poses[:, :3, 3], np.tile([0.0, 0.0, 1.0], (len(f.poses), 1)))
    assert source.frames_dropped == 0
    assert source.packets_lost == 0
    assert source.packets_malformed == 0


def test_a_slow_consumer_loses_whole_frames_never_parts_of_them() -> None:
    """The consumer takes 0.25 s a frame against frames of 0.1 s: with room for one,
    the older frames go whole, and each frame handed on is complete."""
    with avia(1.5) as (client, _):
        source = LiveSource(client, MountGeometry(), period_s=0.1, max_frames=1, duration_s=1.2)
        stamps = []
        for s in source:
            stamps.append(s.frame.stamp)
            assert len(s.frame) == pytest.approx(0.1 / (DT * 1e-9) / STRIDE, abs=2)
            time.sleep(0.25)
    assert source.frames_dropped >= 3
    assert np.all(np.diff(stamps) > 0.15)  # frames were skipped, in order
    # each of the stream's 15 frames once at most (the last is complete too: the device's
    # last packet fires past 1.5 s)
    assert source.frames_dropped + source.frames_delivered <= 15


@pytest.mark.slow
def test_a_silent_device_ends_the_run_with_its_name() -> None:
    with avia(2.0, stall_s=0.3) as (client, dev):
        source = LiveSource(client, MountGeometry(), period_s=0.1)
        frames = iter(source)
        for _ in range(2):
            next(frames)
        dev.paused = True
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match="Livox"):
            list(frames)
        assert time.monotonic() - t0 < 2.0


class _Turret:
    """A turret that reports a fixed pan on the host's clock and records commands."""

    def __init__(self) -> None:
        self.commands: list[TurretCommand] = []

    def state(self) -> TurretState:
        return TurretState(time.monotonic(), 0.5, -0.1)

    def command(self, command: TurretCommand) -> None:
        self.commands.append(command)


class _Stage:
    """Commands the turret every frame, after ``delay_s`` of work."""

    def __init__(self, delay_s: float) -> None:
        self.delay_s = delay_s

    def step(self, frame: Frame) -> StepResult:
        time.sleep(self.delay_s)
        cmd = TurretCommand(frame.end, "position", 0.0, 0.0)
        return StepResult(frame.end, "track", None, len(frame), len(frame), cmd, 0.0)


class _Keep:
    def __init__(self) -> None:
        self.results: list[tuple[Sample, StepResult]] = []

    def write(self, sample: Sample, result: StepResult) -> None:
        self.results.append((sample, result))


@pytest.mark.slow
def test_the_run_loop_measures_the_latency_to_the_command() -> None:
    """latency: the frame's last packet's arrival to its command; at least the stage's
    20 ms of work, and the turret's readings place the sensor at its pan."""
    turret, keep = _Turret(), _Keep()
    with avia(1.0) as (client, _):
        source = LiveSource(client, MountGeometry(), turret, period_s=0.1, duration_s=0.4)
        run(source, _Stage(0.02), turret, [keep])
    assert len(keep.results) == 4
    assert len(turret.commands) == 4
    latency = np.array([r.latency_ms for _, r in keep.results])
    assert np.all(latency >= 20.0)
    assert np.all(latency < 200.0)
    for sample, _ in keep.results:
        axis = sample.frame.poses[-1, :3, 0]  # the sensor's x axis in the world
        assert np.arctan2(axis[1], axis[0]) == pytest.approx(0.5, abs=1e-9)


class _SkyBands:
    """A point source with a return at 0, then returns only 20-60 ms into each 100 ms
    (every 10th firing), open sky the rest: with frames from the first point, a
    frame's last return comes 40 ms before its end, and the next 20 ms after it.
    0.5 s of it, in 10 ms chunks that say how far they cover."""

    def __iter__(self) -> Iterator[PointChunk]:
        for c in range(50):
            k = np.arange(c * 2_400, (c + 1) * 2_400, STRIDE, dtype=np.int64)
            t = k * DT
            band = (t % 100_000_000 >= 20_000_000) & (t % 100_000_000 < 60_000_000)
            k = k[band | (k == 0)]
            yield PointChunk(grid_points(k), k * DT, np.ones(len(k), np.uint8),
                             end_ns=(c + 1) * 10_000_000)  # fmt: skip


@pytest.mark.slow
def test_a_frame_is_handed_on_at_its_end_not_at_the_next_return() -> None:
    """The sky's firings (zero range) complete a frame: each frame is handed on as
    its last packet arrives, not 60 ms later with the next return (measured here, from
    that packet's arrival to the frame in hand: 0.5-1.3 ms; waiting for the next
    return, 61-62 ms; 30 ms leaves room for a loaded machine)."""
    dev = EmulatedLivox(_SkyBands(), device_port=0)
    ep = LivoxEndpoint(LOOP, None, 0, 0, 0, dev.address[1])
    client = LivoxClient(ep, discover_s=0.0)
    waits, counts = [], []
    try:
        dev.start()
        client.open(timeout_s=2.0)
        for sample in LiveSource(client, MountGeometry(), period_s=0.1, duration_s=0.4):
            assert sample.received is not None
            waits.append(time.perf_counter() - sample.received)
            counts.append(len(sample.frame))
    finally:
        client.close()
        dev.close()
    assert len(waits) == 4
    # 40 ms of every 10th firing at 4.167 µs: 960 points (and the first frame's at 0)
    assert counts == [961, 960, 960, 960]
    assert max(waits) < 0.030


class _Polled:
    """A turret that polls itself: readings every 10 ms on the host's clock, the pan
    turning at ω = 0.5 rad/s from its first reading; ``until`` of each call is kept."""

    OMEGA = 0.5

    def __init__(self) -> None:
        self.h0: float | None = None
        self.last = -np.inf
        self.asked: list[float] = []

    def state(self) -> TurretState:  # pragma: no cover - the source reads readings
        raise AssertionError("a polled turret is not read by state")

    def readings(self, until: float = -np.inf, timeout_s: float = 1.0) -> list[TurretState]:
        self.asked.append(until)
        now = time.monotonic()
        if self.h0 is None:
            self.h0 = self.last = now - 0.2
        stamps = np.arange(self.last + 0.01, now, 0.01)
        if len(stamps):
            self.last = float(stamps[-1])
        w = self.OMEGA
        return [TurretState(float(h), w * (h - self.h0), 0.0, pan_rate=w) for h in stamps]


def test_a_polled_turrets_readings_give_every_pose_of_the_frame() -> None:
    """The readings of a turret turning at a constant rate, stamped on the host's clock,
    put the sensor at ω (h − h₀) at every pose time h of the frame (interpolated between
    readings, carried on at the newest's rate after it), and each frame asks for
    readings fresh up to its end on the host's clock."""
    turret = _Polled()
    with avia(1.0) as (client, _):
        source = LiveSource(client, MountGeometry(), turret, period_s=0.1, duration_s=0.4)
        samples = list(source)
    assert len(samples) == 4
    assert turret.h0 is not None
    for sample, until in zip(samples, turret.asked, strict=True):
        frame = sample.frame
        # δ only grows as smaller delays are seen (by µs on loopback): 1 ms bounds it
        assert source.host_time(frame.end) == pytest.approx(until, abs=1e-3)
        axis = frame.poses[:, :3, 0]  # the sensor's x axis in the world at each pose time
        pan = np.arctan2(axis[:, 1], axis[:, 0])
        hosts = np.array([source.host_time(t) for t in frame.pose_t])
        w = _Polled.OMEGA
        np.testing.assert_allclose(pan, w * (hosts - turret.h0), atol=w * 1e-3)


def test_the_queue_needs_room() -> None:
    with pytest.raises(ConfigError, match="room"):
        LiveSource(None, MountGeometry(), max_frames=0)  # type: ignore[arg-type]


class _Broken:
    """A stream whose socket fails on the second read."""

    name = "test stream"
    packets_lost = 0
    packets_malformed = 0

    def __init__(self) -> None:
        self.reads = 0

    def read(self, timeout_s: float = 0.1) -> PointBatch:
        self.reads += 1
        if self.reads > 1:
            raise OSError("network is unreachable")
        time.sleep(0.01)
        return PointBatch(
            np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.uint8), np.zeros(0, np.uint8)
        )

    def close(self) -> None:
        pass


def test_a_socket_error_ends_the_run_naming_the_stream() -> None:
    """Not a silent end: the error reaches the run loop as a device error."""
    source = LiveSource(_Broken(), MountGeometry())
    with pytest.raises(DeviceError, match="test stream: network is unreachable"):
        list(source)


class _Scripted:
    """A stream that hands out given batches (times in ns) 20 ms apart, noting when it
    handed each one out, then nothing."""

    name = "scripted stream"
    packets_lost = 0
    packets_malformed = 0

    def __init__(self, times_ns: list[list[int]]) -> None:
        self.batches = [np.array(t, np.int64) for t in times_ns]
        self.handed: list[float] = []

    def read(self, timeout_s: float = 0.1) -> PointBatch:
        if len(self.handed) == len(self.batches):
            time.sleep(timeout_s)
            t = np.zeros(0, np.int64)
        else:
            time.sleep(0.02)
            t = self.batches[len(self.handed)]
            self.handed.append(time.perf_counter())
        n = len(t)
        return PointBatch(np.ones((n, 3)), t, np.zeros(n, np.uint8), np.zeros(n, np.uint8))

    def close(self) -> None:
        pass


MS = 1_000_000  # ns


def test_a_frame_arrived_with_the_batch_that_held_its_last_point() -> None:
    """Frame 0 (5.00-5.10 s) is completed by a batch wholly of frame 1: its last point
    came with the batch before.  Frame 1 is completed by a batch that reaches into
    it: that batch.  Frame 2 by a batch of frame 3: the one before."""
    base = 5_000 * MS
    stream = _Scripted(
        [
            [base + k * 10 * MS for k in range(10)],  # 5.00-5.09 s: frame 0
            [base + k * 10 * MS for k in range(10, 15)],  # 5.10-5.14 s: frame 1
            [base + k * 10 * MS for k in range(15, 26)],  # 5.15-5.25 s: frames 1, 2
            [base + k * 10 * MS for k in range(30, 36)],  # 5.30-5.35 s: frame 3
        ]
    )
    source = LiveSource(stream, MountGeometry(), period_s=0.1, duration_s=0.3)
    samples = list(source)
    assert [round(s.frame.stamp, 9) for s in samples] == [0.0, 0.1, 0.2]
    b1, _, b3, b4 = stream.handed
    got = [s.received for s in samples]
    assert all(r is not None for r in got)
    # read off the stream after it was handed out, before the next one
    assert b1 <= got[0] < stream.handed[1]  # type: ignore[operator]
    assert b3 <= got[1] < b4  # type: ignore[operator]
    assert b3 <= got[2] < b4  # type: ignore[operator]


def test_the_truth_in_the_sensors_time_base_is_shifted_to_the_runs_clock() -> None:
    """The points' clock starts at 5 s (a synchronised device); the truth x = t on that
    clock, so at a frame's end e on the run's clock the target is at x = 5 + e."""
    from dronetrack.sources.truth import GroundTruth

    base = 5_000 * MS
    stream = _Scripted([[base + k * 10 * MS for k in range(j, j + 10)] for j in (0, 10, 20, 30)])
    truth = GroundTruth(np.array([5.0, 6.0]), np.array([[5.0, 0.0, 1.0], [6.0, 0.0, 1.0]]))
    source = LiveSource(stream, MountGeometry(), period_s=0.1, duration_s=0.3, truth=truth)
    samples = list(source)
    assert len(samples) == 3
    for s in samples:
        assert s.truth is not None
        assert s.truth.target_position[0] == pytest.approx(5.0 + s.frame.end, abs=1e-9)


@pytest.mark.slow
def test_a_stop_request_ends_the_wait_for_a_frame(monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C or SIGTERM while no frame is complete: the iteration ends at once."""
    import dronetrack.sources.frame_queue as frame_queue

    monkeypatch.setattr(frame_queue, "stop_requested", lambda: True)
    stream = _Scripted([[0, 1]])
    t0 = time.monotonic()
    assert list(LiveSource(stream, MountGeometry(), period_s=0.1)) == []
    assert time.monotonic() - t0 < 1.0


def test_a_truth_file_is_read_as_it_grows(tmp_path: object) -> None:
    """emulate writes the truth while the run goes: rows count once their line is
    complete; a bad value or a time going back names the file and line."""
    from pathlib import Path

    from dronetrack.errors import InputError
    from dronetrack.sources.truth_csv import TruthFile

    path = Path(str(tmp_path)) / "truth.csv"
    path.write_text("t,x,y,z\n")
    truth = TruthFile(path)
    assert truth.ground_truth() is None
    with path.open("a") as fh:
        fh.write("0.0,1,2,3\n0.5,2,2,3\n1.0,3,2")  # the last line not finished yet
    g = truth.ground_truth()
    assert g is not None
    np.testing.assert_allclose(g.t, [0.0, 0.5])
    np.testing.assert_allclose(g.at(0.25)[0], [1.5, 2.0, 3.0])
    with path.open("a") as fh:
        fh.write(",3\n")
    g = truth.ground_truth()
    assert g is not None
    np.testing.assert_allclose(g.position[-1], [3.0, 2.0, 3.0])
    with path.open("a") as fh:
        fh.write("0.9,3,2,3\n")
    with pytest.raises(InputError, match="line 5: t must not decrease"):
        truth.ground_truth()
    path.write_text("t,x,y\n")
    with pytest.raises(InputError, match="missing column"):
        TruthFile(path)
    with pytest.raises(InputError, match="not found"):
        TruthFile(path.with_name("none.csv"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # a bad row: the column, the value and why it is refused, then the row
        ("t,x,y,z\n0,1,2,3\n1.0,abc,2,3\n", "line 3: x is 'abc', not a number: '1.0,abc,2,3'"),
        ("t,x,y,z\n0,1,nan,3\n", "line 2: y is 'nan', not a finite number: '0,1,nan,3'"),
        ("t,x,y,z\n0,1,2\n", "line 2: 3 value(s), too few for column z (column 4 of the header)"),
        ("t,x,y,z\n1,1,2,3\n0.5,1,2,3\n", "line 3: t must not decrease; it goes back from 1 to"),
        # a wrong header: the header found
        ("time,x,y,z\n0,1,2,3\n", "missing column(s): t; its header is 'time,x,y,z'"),
        ("0.1,15,0,0.15\n", "missing column(s): t, x, y, z; its header is '0.1,15,0,0.15'"),
    ],
)
def test_a_bad_truth_file_says_what_is_wrong(tmp_path: object, text: str, message: str) -> None:
    """Each refusal names the file, the line, the column and the reason, or the header
    it found where t,x,y,z were expected."""
    from pathlib import Path

    from dronetrack.errors import InputError
    from dronetrack.sources.truth_csv import TruthFile

    path = Path(str(tmp_path)) / "truth.csv"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        TruthFile(path)
    assert message in str(err.value)
    assert str(path) in str(err.value)


def test_truth_file_keeps_every_row_as_it_grows_past_its_buffer(tmp_path: object) -> None:
    """Rows arriving over many reads, past the buffer's first capacity: every row is
    kept in order, and a truth given out earlier does not change as rows are added."""
    from pathlib import Path

    from dronetrack.sources.truth_csv import TruthFile

    path = Path(str(tmp_path)) / "truth.csv"
    path.write_text("t,x,y,z\n")
    truth = TruthFile(path)
    t = np.arange(1000) * 0.02
    earlier = []
    for chunk in np.array_split(np.arange(1000), 7):
        with path.open("a") as fh:
            fh.writelines(f"{t[i]:.2f},{i},{-i},{2 * i}\n" for i in chunk)
        g = truth.ground_truth()
        assert g is not None
        earlier.append((g, chunk[-1]))
    for g, last in earlier:
        n = last + 1
        np.testing.assert_allclose(g.t, t[:n])
        np.testing.assert_allclose(g.position, np.c_[np.arange(n), -np.arange(n), 2 * np.arange(n)])
