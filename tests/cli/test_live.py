"""``dronetrack live`` and ``dronetrack info`` of live devices, on loopback: the emulated
Avia and XM430s, a recording played at wall-clock speed, bad options, a device that
falls silent, SIGTERM, and the live Foxglove server.  Every wait has a deadline."""

from __future__ import annotations

import csv
import json
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.rig import make_turret
from dronetrack.formats.dynamixel import ADDR
from dronetrack.sim.emulate.livox import MID40, EmulatedLivox, GridSource
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sim.emulate.ptu import EmulatedPtu
from dronetrack.sim.emulate.ptu_link import PtyPtuLink
from dronetrack.sim.emulate.servos import PtyServoLink, ServoBus, turret_bus
from foxglove_helpers import ws_messages

LIVE_METRICS = {"latency_ms_p50", "latency_ms_p99", "frames_dropped", "packets_lost",
                "packets_malformed"}  # fmt: skip


def _write_bag(path: Path, frames: int) -> None:
    """A ROS 1 bag of hand-made 0.1 s frames (no simulator): a 0.5 m cloud of 20 points
    moving at 2 m/s, 30 m in front of a fixed sensor, with its ground truth."""
    from dronetrack.geometry.mount import MountGeometry
    from dronetrack.sinks.bag_writer import RecordingWriter
    from dronetrack.types import Frame

    rng = np.random.default_rng(5)
    mount = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.05), (0.025, 0.0, 0.086))
    writer = RecordingWriter(path, "ros1", mount)
    pose = np.eye(4)
    pose[:3, 3] = (0.025, 0.0, 1.136)
    for k in range(frames):
        t0 = 0.1 * k
        target = np.array([30.0, -3.0 + 0.2 * k, 6.0])
        points = target + rng.normal(0.0, 0.15, (20, 3)) - pose[:3, 3]
        frame = Frame(
            stamp=t0,
            duration=0.1,
            points=points,
            t=np.linspace(t0, t0 + 0.099, 20),
            line=np.zeros(20, dtype=np.uint8),
            intensity=np.full(20, 50.0, dtype=np.float32),
            pose_t=np.array([t0, t0 + 0.1]),
            poses=np.stack([pose, pose]),
        )
        writer.frame(frame, target, np.eye(3))
    writer.close()


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _error_lines(err: str) -> list[str]:
    assert "Traceback" not in err
    return [line for line in err.splitlines() if line.startswith("error:")]


@pytest.mark.parametrize(
    ("args", "problem"),
    [
        (["--lidar", "http://192.168.1.3", "--turret", "none"], "livox://IP"),
        (["--lidar", "livox://999.1.1.1", "--turret", "none"], "not an IPv4"),
        (["--lidar", "livox://192.168.1.3", "--turret", "pantilt://x"], "--turret"),
        (["--lidar", "livox://192.168.1.3", "--turret", "ptu://x"], "serial device's path"),
        (["--lidar", "livox://192.168.1.3", "--turret", "ptu://h:1?baud=9600"], "not TCP"),
        (["--lidar", "livox://192.168.1.3", "--turret", "none", "--host-ip", "x"], "--host-ip"),
        (
            [
                "--lidar",
                "livox://192.168.1.3",
                "--turret",
                "none",
                "--background",
                "b.npz",
                "--scan-s",
                "1",
            ],
            "not both",
        ),
        (["--turret", "none"], "--lidar"),
        (["--lidar", "file:///no/such/flight.bag", "--turret", "none"], "no such recording"),
    ],
)
def test_bad_options_are_one_error_line(
    args: list[str], problem: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["live", *args, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert problem in lines[0]
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_a_recording_plays_at_wall_clock_speed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """40 frames of 0.1 s take 4 s: each is handed on when its end is due; the run
    folder is simulate's, with each frame's latency and the live metrics (served live
    to Foxglove meanwhile, when foxglove-sdk is there)."""
    bag = tmp_path / "flight.bag"
    _write_bag(bag, 40)
    out = tmp_path / "run"
    t0 = time.monotonic()
    args = ["live", "--lidar", f"file://{bag}", "--turret", "none", "--scan-s", "0.5"]
    try:
        import foxglove  # noqa: F401

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            args += ["--foxglove-port", str(s.getsockname()[1])]
    except ImportError:
        pass
    assert run([*args, "--out", str(out)]) == 0
    wall = time.monotonic() - t0
    assert wall >= 4.0 - 0.05  # the last frame ends 4.0 s after the first's start
    assert wall < 4.0 + 10.0  # loading, warming up (kernels cached) and writing
    rows = _rows(out / "frames.csv")
    assert len(rows) == 35  # after the 0.5 s scan
    latency = np.array([float(r["latency_ms"]) for r in rows])
    assert np.all(np.isfinite(latency))
    assert np.all((latency >= 0.0) & (latency < 100.0))  # within its frame period
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) >= LIVE_METRICS
    assert (metrics["frames_dropped"], metrics["packets_lost"]) == (0, 0)
    assert metrics["coverage_pct"] is not None  # the recording's truth scores it
    for name in ("config.toml", "top_view.png"):
        assert (out / name).stat().st_size > 0
    assert "latency p50 / p99" in capsys.readouterr().out


@pytest.fixture
def servos() -> Iterator[tuple[ServoBus, PtyServoLink]]:
    pytest.importorskip("dynamixel_sdk")
    bus = turret_bus(1, 2)
    link = PtyServoLink(bus, lifetime=120.0)
    yield bus, link
    link.close()


@pytest.mark.slow
def test_a_lidar_that_falls_silent_is_one_error_line_and_the_folder_is_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lidar = EmulatedLivox(GridSource(4_167, 10.0, stride=10), device_port=0).start()
    port = lidar.address[1]
    uri = f"livox://127.0.0.1?device_port={port}&cmd_port=0&data_port=0&broadcast_port=0"

    def pause_after_a_second() -> None:
        deadline = time.monotonic() + 30.0
        while lidar.packets_sent < 2_500 and time.monotonic() < deadline:
            time.sleep(0.01)
        lidar.paused = True

    threading.Thread(target=pause_after_a_second, daemon=True).start()
    out = tmp_path / "run"
    try:
        code = run(["live", "--lidar", uri, "--turret", "none", "--scan-s", "0.3", "--out",
                    str(out)])  # fmt: skip
    finally:
        lidar.close()
    assert code == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert "Livox" in lines[0]
    assert "no point packet" in lines[0]
    assert str(out) in lines[0]
    metrics = json.loads((out / "metrics.json").read_text())
    assert "no point packet" in metrics["error"]
    assert len(_rows(out / "frames.csv")) >= 5


@pytest.mark.slow
def test_a_lidar_that_sends_nothing_to_the_host_ip_given_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a device told a host address it cannot reach sends nothing this host receives;
    # on loopback every 127.x address reaches the client, so the device sends nothing
    lidar = EmulatedLivox(GridSource(4_167, 10.0, stride=10), device_port=0)
    lidar.paused = True
    lidar.start()
    port = lidar.address[1]
    uri = f"livox://127.0.0.1?device_port={port}&cmd_port=0&data_port=0&broadcast_port=0"
    out = tmp_path / "run"
    try:
        code = run(["live", "--lidar", uri, "--turret", "none", "--host-ip", "127.0.0.9",
                    "--scan-s", "0.3", "--out", str(out)])  # fmt: skip
    finally:
        lidar.close()
    assert code == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    told = r"no point packet for 1\.\d s; it was told to send to 127\.0\.0\.9:\d+ "
    routed = r"\(this host reaches 127\.0\.0\.1 from 127\.0\.0\.1\): check --host-ip"
    assert re.search(told + routed, lines[0])


@pytest.mark.slow
def test_sigterm_holds_the_turret_keeps_the_files_and_exits_130(
    tmp_path: Path, servos: tuple[ServoBus, PtyServoLink]
) -> None:
    """``live`` in its own process on a 10 s recording and the emulated servos: SIGTERM
    after a few frames ends it with 130, the run folder written and the turret held."""
    bus, link = servos
    bag = tmp_path / "flight.bag"
    _write_bag(bag, 100)
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "dronetrack", "live", "--lidar", f"file://{bag}", "--turret",
           f"dynamixel://{link.device}", "--scan-s", "0.3", "--out", str(out)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60.0
        frames = out / "frames.csv"
        while time.monotonic() < deadline and proc.poll() is None:
            if frames.exists() and len(frames.read_text().splitlines()) > 5:
                break
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()[1]
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=5.0)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    assert "Traceback" not in err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["interrupted"] is True
    assert len(_rows(out / "frames.csv")) >= 5
    assert (out / "config.toml").exists()
    # held: torque on, and the last goal is where the servo was when it was stopped
    assert bus.value(1, ADDR.TORQUE_ENABLE) == 1
    assert len(bus.servo(1).goals) >= 5
    assert abs(bus.value(1, ADDR.GOAL_POSITION) - bus.value(1, ADDR.PRESENT_POSITION)) <= 50


@pytest.mark.slow
def test_a_turret_at_another_baud_rate_is_one_error_line_naming_the_rate(
    tmp_path: Path,
    servos: tuple[ServoBus, PtyServoLink],
    capsys: pytest.CaptureFixture[str],
) -> None:
    pytest.importorskip("serial")
    _, link = servos
    bag = tmp_path / "flight.bag"
    _write_bag(bag, 10)
    ptu = PtyPtuLink(EmulatedPtu.from_turret(make_turret("ptu-e46")), lifetime=60.0)
    turrets = {
        f"dynamixel://{link.device}?baud=57600": "no servo answered at 57600 baud",
        f"ptu://{ptu.device}?baud=38400": "no answer at 38400 baud",
    }
    try:
        for turret, problem in turrets.items():
            args = ["live", "--lidar", f"file://{bag}", "--turret", turret, "--scan-s", "0"]
            assert run([*args, "--out", str(tmp_path / "run")]) == 2
            lines = _error_lines(capsys.readouterr().err)
            assert len(lines) == 1
            assert problem in lines[0]
    finally:
        ptu.close()


def test_info_of_servos_at_another_baud_rate_is_one_error_line_naming_the_rate(
    servos: tuple[ServoBus, PtyServoLink], capsys: pytest.CaptureFixture[str]
) -> None:
    _, link = servos
    assert run(["info", f"dynamixel://{link.device}?baud=57600"]) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert f"on {link.device}: no servo answered at 57600 baud" in lines[0]


def test_a_velodyne_against_a_livox_scenario_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The default scenario's sensor is an Avia: a VLP-16's stream is refused before
    anything is opened (its frames, head mount and scan would be guesses)."""
    args = ["live", "default", "--lidar", f"velodyne://127.0.0.1:{_free_udp_port()}"]
    assert run([*args, "--turret", "none", "--out", str(tmp_path / "run")]) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert "VLP-16" in lines[0]
    assert "'avia'" in lines[0]
    assert "vlp16-side" in lines[0]
    assert not (tmp_path / "run").exists()


def test_a_livox_of_another_model_is_run_as_what_it_says_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An emulated Mid-40 (device type 1 in its discovery broadcast) against the default
    scenario's Avia: one warning line naming both, and config.toml records the Mid-40."""
    listen = _free_udp_port()
    lidar = EmulatedLivox(
        GridSource(10_000, 5.0, stride=10),
        dev_type=MID40,
        device_port=0,
        broadcast_to=("127.0.0.1", listen),
        broadcast_period_s=0.1,
    ).start()
    port = lidar.address[1]
    uri = f"livox://127.0.0.1?device_port={port}&cmd_port=0&data_port=0&broadcast_port={listen}"
    out = tmp_path / "run"
    args = ["live", "default", "--lidar", uri, "--turret", "none", "--scan-s", "0.3"]
    try:
        assert run([*args, "--duration", "0.5", "--out", str(out)]) == 0
    finally:
        lidar.close()
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning:" in line]
    assert len(warnings) == 1
    assert "Livox Mid-40 (device type 1" in warnings[0]
    assert "'avia'" in warnings[0]
    config = (out / "config.toml").read_text()
    assert 'model = "mid40"' in config
    assert 'model = "avia"' not in config


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_info_of_a_livox_device(capsys: pytest.CaptureFixture[str]) -> None:
    listen = _free_udp_port()
    lidar = EmulatedLivox(
        GridSource(4_167, 5.0, stride=10),
        device_port=0,
        broadcast_to=("127.0.0.1", listen),
        broadcast_period_s=0.1,
        firmware=(3, 1, 2, 4),
    ).start()
    port = lidar.address[1]
    uri = f"livox://127.0.0.1?device_port={port}&cmd_port=0&data_port=0&broadcast_port={listen}"
    try:
        assert run(["info", uri]) == 0
    finally:
        lidar.close()
    out = capsys.readouterr().out
    assert "device: Livox Avia at 127.0.0.1" in out
    assert "device type: 7" in out
    assert "broadcast code: 0EMULATEDLIVOX1" in out
    assert "firmware: 3.1.2.4" in out
    sampled = next(line for line in out.splitlines() if line.startswith("sampling"))
    assert "0 lost, 0 malformed" in sampled
    assert int(sampled.split(": ")[1].split()[0]) > 500  # packets in 0.5 s of 2,500/s


def test_info_of_a_livox2_device(capsys: pytest.CaptureFixture[str]) -> None:
    lidar = EmulatedLivox2(
        GridSource(5_000, 5.0, stride=10),
        discovery_port=0,
        cmd_port=0,
        push_port=0,
        point_port=0,
        serial="47MDL9W0020022",
        firmware=(10, 11, 6, 35),
    ).start()
    (_, port), (_, detect) = lidar.address, lidar.discovery_address
    uri = (
        f"livox2://127.0.0.1?device_port={port}&device_discovery_port={detect}"
        "&cmd_port=0&point_port=0&discovery_port=0&broadcast=0"
    )
    try:
        assert run(["info", uri]) == 0
    finally:
        lidar.close()
    out = capsys.readouterr().out
    for line in (
        "device: Livox Mid-360 at 127.0.0.1",
        "device type: 9",
        "serial number: 47MDL9W0020022",
        "product: Mid-360 emulated",
        "firmware: 10.11.6.35",
        "loader version: 0.1.0.0",
        "hardware version: 0.0.0.1",
        "MAC: 02:00:00:00:03:60",
        "work state: 0x02 IDLE",
    ):
        assert line in out.splitlines()
    sampled = next(line for line in out.splitlines() if line.startswith("sampling"))
    assert "0 lost, 0 malformed" in sampled
    # 0.5 s of 200,000 points/s, every 10th point a return: packets at 2,083/s
    assert int(sampled.split(": ")[1].split()[0]) > 500


def test_info_of_the_servos(
    servos: tuple[ServoBus, PtyServoLink], capsys: pytest.CaptureFixture[str]
) -> None:
    bus, link = servos
    assert run(["info", f"dynamixel://{link.device}"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("servo ID 1 (pan): model 1020, firmware 48, present position 2048")
    assert out[1].startswith("servo ID 2 (tilt): model 1020")
    bus.set_online(2, False)
    assert run(["info", f"dynamixel://{link.device}"]) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert "ID 2 (tilt)" in lines[0]


@pytest.mark.slow
def test_the_foxglove_port_prints_its_address_and_the_sdks_log_is_a_warning_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--foxglove-port`` says where to connect; a client the server drops (plain HTTP)
    gets one ``warning:`` line of ours, not the SDK's bare log line."""
    pytest.importorskip("foxglove")
    bag = tmp_path / "flight.bag"
    _write_bag(bag, 20)
    port = _free_tcp_port()

    def refused_client() -> None:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1.0) as conn:
                    conn.sendall(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n")
                    conn.settimeout(2.0)
                    conn.recv(1024)
                return
            except OSError:
                time.sleep(0.05)

    client = threading.Thread(target=refused_client, daemon=True)
    client.start()
    args = ["live", "--lidar", f"file://{bag}", "--turret", "none", "--scan-s", "0.5"]
    assert run([*args, "--foxglove-port", str(port), "--out", str(tmp_path / "run")]) == 0
    client.join(timeout=5.0)
    err = capsys.readouterr().err.splitlines()
    assert any(line.startswith(f"foxglove: ws://127.0.0.1:{port}") for line in err), err
    dropped = [line for line in err if "Dropping client" in line]
    assert dropped, err
    assert all(line.startswith("warning: Foxglove SDK: Dropping client") for line in dropped)


def _free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_live_foxglove_server_advertises_the_runs_topics() -> None:
    pytest.importorskip("foxglove")
    from dronetrack.sinks.foxglove.live import FoxgloveServer
    from dronetrack.sinks.foxglove.mcap_file import TOPICS

    server = FoxgloveServer(0)
    try:
        advertised: set[str] = set()
        for message in ws_messages(server.port, 5.0):
            if message.get("op") == "advertise":
                channels = message["channels"]
                assert isinstance(channels, list)
                advertised |= {c["topic"] for c in channels}
            if advertised >= set(TOPICS):
                break
        assert advertised >= set(TOPICS)
    finally:
        server.close()
