"""A run with a ``[site]``: tracks.csv's WGS-84 and azimuth-elevation-range columns
against pymap3d applied here to its world columns, the zones' alerts.jsonl, and the
``--sapient`` option's bad input."""

from __future__ import annotations

import csv
import json
import math
import socket
import struct
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d
import pytest

from dronetrack.cli.main import run
from dronetrack.config.rig import turret_spec
from dronetrack.config.run import load_scenario_file
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.sinks.run_folder import GEO_COLUMNS
from sapient_helpers import node_registration, official_decoder

SITE = """
base = "indoor-vertical"
duration_s = 4.0
seed = 3

[site]
latitude_deg = 51.5
longitude_deg = -0.12
altitude_m = 30.0
heading_deg = 120.0

[[zones]]
name = "room"
centre = [51.5, -0.12]
radius_m = 50.0
margin_m = 5.0
"""


def _base_height(run_dir: Path) -> float:
    """The run's turret base above the world origin [m], from its config.toml."""
    cfg = load_scenario_file(run_dir / "config.toml", SCENARIOS)
    assert turret_spec(cfg.turret).mount.base[:2] == (0.0, 0.0)
    return turret_spec(cfg.turret).mount.base[2]


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_tracks_carry_where_they_are_on_the_earth(tmp_path: Path) -> None:
    config = tmp_path / "site.toml"
    config.write_text(SITE + "\n[pipeline.tracker]\nparticles = 1000\n")
    out = tmp_path / "run"
    assert run(["simulate", "--config", str(config), "--out", str(out)]) == 0
    rows = _rows(out / "tracks.csv")
    assert rows
    assert set(GEO_COLUMNS) <= set(rows[0])
    base_z = _base_height(out)
    # world x is 120° from north: ENU = Rz(90° − 120°) (p − base)
    theta = math.radians(90.0 - 120.0)
    for r in rows:
        x, y, z = float(r["x"]), float(r["y"]), float(r["z"]) - base_z
        e = math.cos(theta) * x - math.sin(theta) * y
        n = math.sin(theta) * x + math.cos(theta) * y
        lat, lon, alt = pymap3d.enu2geodetic(e, n, z, 51.5, -0.12, 30.0)
        az, el, rng = pymap3d.enu2aer(e, n, z)
        # tracks.csv rounds x, y, z to 1 µm and lat, lon to 1e-9° (0.1 mm)
        assert float(r["lat_deg"]) == pytest.approx(lat, abs=2e-9)
        assert float(r["lon_deg"]) == pytest.approx(lon, abs=2e-9)
        assert float(r["alt_m"]) == pytest.approx(alt, abs=1e-5)
        assert float(r["range_m"]) == pytest.approx(rng, abs=1e-5)
        assert float(r["elevation_deg"]) == pytest.approx(el, abs=1e-4)
        if math.hypot(e, n) > 0.01:
            assert float(r["azimuth_deg"]) == pytest.approx(az, abs=1e-3)
    # the zone was given: its alerts file is there, each line a JSON object naming it
    lines = (out / "alerts.jsonl").read_text().splitlines()
    for line in lines:
        record = json.loads(line)
        assert record["zone"] == "room"
        assert record["kind"] in ("predicted", "margin", "inside", "clear")
    # the hovering Crazyflie is in the zone: once its track is classed drone, an alert
    drones = [r for r in rows if r["class"] == "drone"]
    if drones:
        first = json.loads(lines[0])
        assert (first["kind"], first["track_id"]) == ("inside", int(drones[0]["id"]))
        assert first["t"] == pytest.approx(float(drones[0]["t"]))
    else:
        assert lines == []
    assert "[site]" in (out / "config.toml").read_text()


def test_without_a_site_only_elevation_and_range_are_known(tmp_path: Path) -> None:
    out = tmp_path / "run"
    argv = ["simulate", "indoor-vertical", "--duration", "3", "--particles", "500"]
    assert run([*argv, "--out", str(out)]) == 0
    rows = _rows(out / "tracks.csv")
    assert rows
    for r in rows:
        assert all(r[c] == "nan" for c in ("lat_deg", "lon_deg", "alt_m", "azimuth_deg"))
        p = np.array([float(r["x"]), float(r["y"]), float(r["z"]) - _base_height(out)])
        assert float(r["range_m"]) == pytest.approx(np.linalg.norm(p), abs=1e-5)
    assert not (out / "alerts.jsonl").exists()


@pytest.mark.parametrize(
    ("endpoint", "message"),
    [
        ("127.0.0.1:1", "--sapient needs the site's coordinates"),
    ],
)
def test_sapient_without_a_site_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], endpoint: str, message: str
) -> None:
    out = tmp_path / "run"
    assert run(["simulate", "--sapient", endpoint, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("error: ")
    assert message in err[0]
    assert not out.exists()


class _FusionNode:
    """A fusion node of the test's own: it acknowledges the registration with the
    independent decoder's classes and keeps every message, decoded by them."""

    def __init__(self) -> None:
        self.official = official_decoder()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.server.settimeout(0.2)
        self.port = self.server.getsockname()[1]
        self.messages: list[Any] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        deadline = time.monotonic() + 300.0
        while not self.stop.is_set() and time.monotonic() < deadline:
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.2)
                buf = b""
                while not self.stop.is_set() and time.monotonic() < deadline:
                    try:
                        data = conn.recv(65536)
                    except TimeoutError:
                        continue
                    if not data:
                        break
                    buf += data
                    while len(buf) >= 4 and len(buf) >= 4 + struct.unpack("<I", buf[:4])[0]:
                        size = struct.unpack("<I", buf[:4])[0]
                        msg = self.official.FromString(buf[4 : 4 + size])
                        buf = buf[4 + size :]
                        self.messages.append(msg)
                        if msg.WhichOneof("content") == "registration":
                            ack = self.official(node_id="fusion")
                            ack.registration_ack.acceptance = True
                            body = ack.SerializeToString()
                            conn.sendall(struct.pack("<I", len(body)) + body)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5.0)
        self.server.close()


def test_every_detection_report_is_where_tracks_csv_says(tmp_path: Path) -> None:
    """``simulate --sapient`` on ``default`` with a site: each DetectionReport, decoded
    from the official .proto files, lies within 0.5 m of its tracks.csv row converted
    with pymap3d (the row of its track at its frame's time)."""
    pytest.importorskip("google.protobuf")
    pytest.importorskip("grpc_tools")
    config = tmp_path / "site.toml"
    config.write_text(
        'base = "default"\nduration_s = 8.0\n'
        + "[site]\nlatitude_deg = 47.4\nlongitude_deg = 19.2\naltitude_m = 120.0\n"
        + "heading_deg = 30.0\n"
    )
    fusion = _FusionNode()
    out = tmp_path / "run"
    try:
        argv = ["simulate", "--config", str(config), "--out", str(out)]
        assert run([*argv, "--sapient", f"127.0.0.1:{fusion.port}"]) == 0
        kinds = [m.WhichOneof("content") for m in fusion.messages]
        assert kinds[0] == "registration"
        assert "status_report" in kinds
    finally:
        fusion.close()
    rows = {(r["id"], r["t"]): r for r in _rows(out / "tracks.csv")}
    reports = [m.detection_report for m in fusion.messages if m.HasField("detection_report")]
    checked = 0
    for report in reports:
        info = {i.type: i.value for i in report.track_info}
        if report.state == "lost":
            continue
        t = info["frame_t_s"].rstrip("0").rstrip(".")
        row = rows[(info["track_id"], t)]
        x, y, z = float(row["x"]), float(row["y"]), float(row["z"]) - 1.0  # base 1 m up
        theta = math.radians(90.0 - 30.0)
        e = math.cos(theta) * x - math.sin(theta) * y
        n = math.sin(theta) * x + math.cos(theta) * y
        truth = np.array(pymap3d.geodetic2ecef(*pymap3d.enu2geodetic(e, n, z, 47.4, 19.2, 120.0)))
        loc = report.location
        got = np.array(pymap3d.geodetic2ecef(loc.y, loc.x, loc.z))
        assert np.linalg.norm(got - truth) < 0.5
        assert row["class"] in (report.classification[0].type, "static")
        checked += 1
    assert checked > 20  # the drone, tracked from about 11 s of the 18 s run


def test_sapient_listen_refuses_a_bad_look_at(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("google.protobuf")
    for bad in ("47.4", "47.4,x", "95,19", "1,2,3,4", "47.4,19.2,inf", "nan,19"):
        assert run(["sapient-listen", "--port", "0", "--look-at", bad, "--duration", "0"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1
        assert err[0].startswith("error: --look-at")


def test_sapient_listen_writes_what_it_receives(tmp_path: Path) -> None:
    pytest.importorskip("google.protobuf")
    from dronetrack.formats.sapient import messages as m
    from dronetrack.sinks.sapient.link import SapientLink

    port = 0
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "c2.jsonl"

    def join() -> None:
        link = SapientLink("127.0.0.1", port, node_registration)
        deadline = time.monotonic() + 10.0
        while not link.stats.registered and time.monotonic() < deadline:
            time.sleep(0.02)
        link.send(m.task_ack("n", time.time(), "hello", True))
        time.sleep(0.3)
        link.close()

    thread = threading.Thread(target=join, daemon=True)
    thread.start()
    argv = ["sapient-listen", "--port", str(port), "--out", str(out), "--duration", "3"]
    assert run(argv) == 0
    thread.join(5.0)
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert [next(k for k in r if k in ("registration", "task_ack")) for r in records] == [
        "registration",
        "task_ack",
    ]
    assert records[1]["task_ack"]["task_id"] == "hello"
    assert all(r["peer"].startswith("127.0.0.1:") for r in records)


def test_a_fusion_node_that_is_not_there_does_not_stop_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("google.protobuf")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nobody listens there after this
    config = tmp_path / "site.toml"
    config.write_text(SITE)
    out = tmp_path / "run"
    argv = ["simulate", "--config", str(config), "--out", str(out)]
    assert run([*argv, "--sapient", f"127.0.0.1:{port}"]) == 0
    err = capsys.readouterr().err
    assert f"sapient: cannot reach the fusion node at 127.0.0.1:{port}" in err
    assert "messages sent, " in err
    assert len(_rows(out / "frames.csv")) == 40  # every frame of the 4 s run
    for bad in ("127.0.0.1", "127.0.0.1:0", "host:port"):
        assert run([*argv, "--sapient", bad]) == 2
        assert "give the fusion node as HOST:PORT" in capsys.readouterr().err
