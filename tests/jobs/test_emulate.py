"""The emulated rig driven by the real host-side clients on loopback: the Livox clients
(SDK 1 and 2) over UDP and the Dynamixel turret through the official DYNAMIXEL SDK on
the servos' pseudo-terminal.

Every socket is on 127.0.0.1 with ports the kernel picks, every loop is bounded in
count and time."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from dronetrack.actuators.dynamixel.turret import DynamixelTurret
from dronetrack.config.run import ScenarioConfig
from dronetrack.config.scenarios import get_scenario
from dronetrack.geometry.mount import sensor_poses
from dronetrack.jobs.emulate import TAIL_FRAMES, emulated_rig, emulated_seconds
from dronetrack.sim.emulate.rig import EmulatedRig
from dronetrack.sim.turret import TurretPlant
from dronetrack.sim.world import FrameTruth
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.livox.link import LivoxLink
from dronetrack.sources.livox.sdk1 import LivoxClient, LivoxEndpoint
from dronetrack.sources.livox.sdk2 import Livox2Client, Livox2Endpoint
from dronetrack.types import Frame, TurretCommand

LOOP = "127.0.0.1"


def short(name: str = "default", scan_s: float = 0.5, flight_s: float = 1.0) -> ScenarioConfig:
    """A named scenario with a short background scan and flight."""
    cfg = get_scenario(name)
    background = cfg.pipeline.background.model_copy(update={"scan_s": scan_s})
    pipeline = cfg.pipeline.model_copy(update={"background": background})
    return cfg.model_copy(update={"duration_s": flight_s, "pipeline": pipeline})


def sdk1_client(rig: EmulatedRig) -> LivoxClient:
    return LivoxClient(LivoxEndpoint(LOOP, None, 0, 0, 0, rig.address[1]), discover_s=0.1)


def read_until_finished(
    client: LivoxLink, rig: EmulatedRig, limit_s: float
) -> Iterator[tuple[float, PointBatch]]:
    """(scenario time when read, batch) until the rig's stream has been sent and the
    last packets drained, or ``limit_s`` passes."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline and not rig.finished.is_set():
        batch = client.read(0.05)
        now = rig.scenario_time()
        assert now is not None
        yield now, batch
    for _ in range(5):  # what is still queued
        batch = client.read(0.05)
        if not len(batch):
            return
        yield math.nan, batch


def test_the_host_receives_the_simulated_returns_on_the_scenario_clock(tmp_path: Path) -> None:
    cfg = short()
    truths: list[FrameTruth] = []
    rig = emulated_rig(
        cfg, any_ports=True, truth=tmp_path / "truth.csv", on_slice=lambda f, t: truths.append(t)
    )
    with rig, sdk1_client(rig) as client:
        assert rig.scenario_time() is None  # the clock waits for the host
        client.open(timeout_s=3.0)
        assert rig.started.wait(1.0)
        lead, points, last_t = [], 0, []
        for now, batch in read_until_finished(client, rig, limit_s=10.0):
            if len(batch):
                points += len(batch)
                last_t.append(int(batch.t_ns[-1]))
                if not math.isnan(now):
                    lead.append(batch.t_ns[-1] * 1e-9 - now)
        assert rig.finished.is_set()
        dev = rig.device
        # Every return made reached the host, all but those two sim pulses put on one
        # firing (the sim fires every 1/240 000 s, the device every 4 167 ns: one
        # collision in 12 500 pulses; measured 34 of 370 000 returns in 3.2 s).
        assert client.packets_lost == 0
        assert client.packets_received == dev.packets_sent
        assert points == rig.points - dev.points_dropped
        assert dev.points_dropped <= 2e-4 * rig.points
        assert rig.points > 0
    # The stream is the scenario (scan, flight, tail) in whole slices of 50 Avia packets.
    total = emulated_seconds(cfg)
    assert total == pytest.approx(0.5 + 1.0 + TAIL_FRAMES * 0.1)
    slices = math.ceil(total / rig.slice_s)
    assert rig.slice_s == pytest.approx(50 * 96 * 4_167e-9)
    assert rig.slices == slices
    assert dev.packets_sent == 50 * slices
    # Points carry the scenario clock: never ahead of it by more than the span of the
    # packet being sent (the device sends a packet at its first firing's time: 96
    # firings of 4 167 ns = 0.4 ms), and the last ones end the stream.
    assert max(lead) <= 0.5e-3
    assert last_t[-1] <= round(slices * rig.slice_s * 1e9)
    assert last_t[-1] > round((slices - 1) * rig.slice_s * 1e9)
    # The truth: one row at 0 and at each slice's end, in the packets' time base, with
    # the simulated target's position.
    table = np.loadtxt(tmp_path / "truth.csv", delimiter=",", skiprows=1)
    assert (tmp_path / "truth.csv").read_text().startswith("t,x,y,z\n")
    assert table.shape == (slices + 1, 4)
    np.testing.assert_allclose(table[:, 0], np.arange(slices + 1) * rig.slice_s, atol=1e-9)
    np.testing.assert_allclose(table[1:, 0], [t.t for t in truths], atol=1e-9)
    np.testing.assert_allclose(table[:, 1:], rig.world.trajectory.position(table[:, 0]), atol=1e-6)


def _reference(spec: object, start: tuple[float, float], goal: tuple[float, float], s_cmd: float):
    """The simulator's turret alone: at rest at ``start``, both goals at ``s_cmd``; its
    pointing as a function of scenario time."""
    plant = TurretPlant(spec, pan=start[0], tilt=start[1], t0=s_cmd)  # type: ignore[arg-type]
    plant.command_axis("pan", s_cmd, goal[0])
    plant.command_axis("tilt", s_cmd, goal[1])
    t, pan, tilt = plant.advance(s_cmd + 3.0)
    return lambda s: (float(np.interp(s, t, pan)), float(np.interp(s, t, tilt)))


@pytest.mark.slow
def test_a_goal_moves_the_simulated_turret_with_its_dynamics() -> None:
    slices: list[Frame] = []
    rig = emulated_rig(short(flight_s=2.5), any_ports=True, on_slice=lambda f, t: slices.append(f))
    spec = rig.world.plant.spec
    with rig, sdk1_client(rig) as client:
        turret = DynamixelTurret(rig.serial_device, turret=spec)
        try:
            at_rest = turret.state()
            # Without a goal the turret holds its start pose, before sampling and after.
            client.open(timeout_s=3.0)
            time.sleep(0.2)
            start = turret.state()
            assert (start.pan, start.tilt) == (at_rest.pan, at_rest.tilt)
            goal = (start.pan + 0.4, start.tilt - 0.25)
            before = time.monotonic()
            turret.command(TurretCommand(0.0, *goal))
            after = time.monotonic()
            states = []
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                client.read(0.0)  # keep the host's queue short
                states.append(turret.state())
                time.sleep(0.02)
        finally:
            turret.close()
        anchor = rig.device.stream_start
    assert rig.started.is_set()
    # What the servos report is the sim turret's path: the same plant alone, commanded
    # when the goal arrived (between before and after), read at each state's stamp.
    # Tolerance: the state's stamp is the middle of its exchange, and the goal's arrival
    # is known to (after − before); at the axis rate ω = π rad/s each 5 ms of
    # uncertainty is 16 mrad, plus half a tick (0.77 mrad) for the start pose.
    s_cmd = 0.5 * (before + after) - anchor
    ref = _reference(spec, (start.pan, start.tilt), goal, s_cmd)
    omega = spec.pan.rate
    tol = omega * (0.005 + (after - before)) + spec.pan.resolution
    s = np.array([st.stamp - anchor for st in states])
    got = np.array([[st.pan, st.tilt] for st in states])
    want = np.array([ref(x) for x in s])
    err = np.abs(got - want)
    assert err.max() <= tol, (err.max(), tol)
    # It moves toward the goal, past it by at most the sim's own braking error (one
    # 0.088° step, as the reference plant also does), and arrives within a step.
    q = spec.pan.resolution
    assert np.all(got[:, 0] <= goal[0] + 1.5 * q)
    assert np.all(got[:, 1] >= goal[1] - 1.5 * q)
    np.testing.assert_allclose(got[-1], goal, atol=q)
    moving = (s > s_cmd + 0.1) & (s < s_cmd + 0.3)
    rates = np.array([[st.pan_rate, st.tilt_rate] for st in states])[moving]
    assert np.all(rates[:, 0] > 0)
    assert np.all(rates[:, 1] < 0)
    assert np.all(np.abs(rates) <= omega * 1.05)
    # The slices were made with the pose the servos report: the sensor's x axis in each
    # slice at a state's time is the one the reported angles give, within the tolerance.
    mount = spec.mount
    checked = 0
    for t_s, pan, tilt in zip(s, got[:, 0], got[:, 1], strict=True):
        for frame in slices:
            if frame.pose_t[0] <= t_s <= frame.pose_t[-1]:
                k = int(np.argmin(np.abs(frame.pose_t - t_s)))
                x_frame = frame.poses[k, :3, 0]
                x_servo = sensor_poses(np.array([pan]), np.array([tilt]), mount)[0, :3, 0]
                gap = math.acos(min(1.0, float(x_frame @ x_servo)))
                assert gap <= tol + omega * 1e-3  # + the nearest pose sample's 1 ms
                checked += 1
    assert checked >= 0.9 * len(states)


def test_a_second_start_runs_the_scenario_again_from_its_start(tmp_path: Path) -> None:
    cfg = short(scan_s=0.2, flight_s=0.2)
    rig = emulated_rig(cfg, any_ports=True, truth=tmp_path / "truth.csv")
    with rig:
        for run in (1, 2):
            rig.finished.clear()
            with sdk1_client(rig) as client:
                client.open(timeout_s=3.0)
                first = None
                for _, batch in read_until_finished(client, rig, limit_s=5.0):
                    if first is None and len(batch):
                        first = int(batch.t_ns[0])
            assert rig.starts == run
            assert first is not None
            assert first < 20_000_000  # the clock starts again at 0
            table = np.loadtxt(tmp_path / "truth.csv", delimiter=",", skiprows=1)
            assert table[0, 0] == 0.0
            assert len(table) == rig.slices / run + 1  # rewritten, not appended


def test_a_mid360_scenario_streams_sdk2_packets_at_its_rate() -> None:
    cfg = short("mid360-aggressive", scan_s=0.3, flight_s=0.3)
    rig = emulated_rig(cfg, any_ports=True)
    dev = rig.device
    ep = Livox2Endpoint(LOOP, None, 0, 0, 0, rig.address[1], 0, False)
    with rig, Livox2Client(ep, discover_s=0.1) as client:
        client.open(timeout_s=3.0)
        lead, points = [], 0
        for now, batch in read_until_finished(client, rig, limit_s=5.0):
            points += len(batch)
            if len(batch) and not math.isnan(now):
                lead.append(batch.t_ns[-1] * 1e-9 - now)
        assert client.packets_lost == 0
        assert points == rig.points - dev.points_dropped
    # 42 packets of 96 firings of 5 µs a slice (20.16 ms): 2 083 packets/s
    assert rig.slice_s == pytest.approx(42 * 96 * 5e-6)
    assert dev.packets_sent == 42 * rig.slices
    assert rig.slices == math.ceil(emulated_seconds(cfg) / rig.slice_s)
    assert max(lead) <= 0.5e-3  # a packet spans 95 · 5 µs


# XM430-W350 control table (ROBOTIS e-Manual, Protocol 2.0): torque enable (1 byte),
# goal position and present position (4 bytes each, 4096 ticks a turn).
XM_TORQUE_ENABLE, XM_GOAL_POSITION, XM_PRESENT_POSITION = 64, 116, 132


def test_the_servos_move_before_any_lidar_host_samples() -> None:
    """Ping, torque on, a goal 300 ticks away, with the official DYNAMIXEL SDK and no
    LiDAR host: the servo moves to its goal, as a real XM430 does; the scenario, once a
    host samples, starts from where the turret is."""
    sdk = pytest.importorskip("dynamixel_sdk")
    slices: list[Frame] = []
    rig = emulated_rig(short(flight_s=0.5), any_ports=True, on_slice=lambda f, t: slices.append(f))
    with rig:
        start_pose = rig.turret_at(time.monotonic())
        port = sdk.PortHandler(rig.serial_device)
        assert port.openPort()
        assert port.setBaudRate(1_000_000)
        packets = sdk.PacketHandler(2.0)
        try:
            model, result, error = packets.ping(port, 1)
            assert (model, result, error) == (1020, sdk.COMM_SUCCESS, 0)  # an XM430-W350
            start, result, error = packets.read4ByteTxRx(port, 1, XM_PRESENT_POSITION)
            assert (result, error) == (sdk.COMM_SUCCESS, 0)
            assert packets.write1ByteTxRx(port, 1, XM_TORQUE_ENABLE, 1)[0] == sdk.COMM_SUCCESS
            goal = start + 300  # 26.4°
            assert packets.write4ByteTxRx(port, 1, XM_GOAL_POSITION, goal)[0] == sdk.COMM_SUCCESS
            seen = []
            for _ in range(200):  # 200 reads 10 ms apart: 2 s at most
                present, result, error = packets.read4ByteTxRx(port, 1, XM_PRESENT_POSITION)
                assert (result, error) == (sdk.COMM_SUCCESS, 0)
                seen.append(present)
                if abs(present - goal) <= 1:
                    break
                time.sleep(0.01)
        finally:
            port.closePort()
        assert not rig.started.is_set()  # no host ever sampled
        # it moved to the goal, never back, past it by at most a tick (the sim's braking)
        assert abs(seen[-1] - goal) <= 1
        assert len(seen) > 2  # the move took several reads: it was not a jump
        assert np.all(np.diff(seen) >= 0)
        assert max(seen) <= goal + 1
        moved_pose = rig.turret_at(time.monotonic())
        assert moved_pose[1] == start_pose[1]  # the tilt servo had no goal
        with sdk1_client(rig) as client:
            client.open(timeout_s=3.0)
            for _ in read_until_finished(client, rig, limit_s=5.0):
                pass
    assert rig.started.is_set()
    assert slices
    # the first slice's sensor points where the servo went, not to the start pose
    spec = rig.world.plant.spec
    x_first = slices[0].poses[0, :3, 0]
    x_moved, x_start = sensor_poses(
        np.array([moved_pose[0], start_pose[0]]), np.array([start_pose[1]] * 2), spec.mount
    )[:, :3, 0]
    assert math.acos(min(1.0, float(x_first @ x_moved))) < 2 * spec.pan.resolution
    assert math.acos(min(1.0, float(x_first @ x_start))) > 0.4


def test_the_command_waits_as_long_as_the_job_by_default() -> None:
    """``emulate --wait-s``'s default is the job's (the command loads its job lazily, so it
    cannot import the constant), and options the job rejects are rejected there too."""
    import inspect

    from dronetrack.cli.emulate import emulate
    from dronetrack.errors import ConfigError
    from dronetrack.jobs.emulate import WAIT_S, EmulateOptions

    assert inspect.signature(emulate).parameters["wait_s"].default == WAIT_S
    assert EmulateOptions().wait_s == WAIT_S
    with pytest.raises(ConfigError, match=r"--lidar-dest '10\.0\.0\.1:0'"):
        EmulateOptions(lidar_dest="10.0.0.1:0").check()
    with pytest.raises(ConfigError, match="go with --ros2"):
        EmulateOptions(pointcloud2=True).check()
