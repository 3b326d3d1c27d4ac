"""A live run on a VLP-16 (``velodyne://``) against the emulated sensor in this process:
frames of one revolution or of the integration time as the scenario's sensor says,
``--host-ip``, a silent sensor, and ``dronetrack info velodyne://``."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.run import SensorConfig, apply_overrides
from dronetrack.config.scenarios import get_scenario
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.jobs.live.run import LiveSetup, live_config, run_live
from dronetrack.jobs.live.streams import open_point_stream
from dronetrack.jobs.live.velodyne import velodyne_frames
from dronetrack.sim.emulate.livox_stream import PointChunk
from dronetrack.sim.emulate.velodyne import EmulatedVelodyne
from dronetrack.sim.spinning import vlp16_pattern
from dronetrack.sources.revolutions import RevolutionAssembler
from dronetrack.sources.velodyne.client import VelodyneClient
from dronetrack.types import Sample, StepResult

LOOP = "127.0.0.1"


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((LOOP, 0))
        return int(s.getsockname()[1])


def _wall(duration_s: float) -> Callable[[], Iterator[PointChunk]]:
    """Every 8th pulse of a VLP-16 at 600 rpm returns from 20 m, for ``duration_s``."""
    pattern = vlp16_pattern(600.0)

    def source() -> Iterator[PointChunk]:
        for k in range(round(duration_s / 0.02)):
            p = pattern.pulses(0.02 * k, 0.02 * (k + 1))
            xyz = (p.origins + 20.0 * p.dirs)[::8]
            t_ns = np.rint(p.t[::8] * 1e9).astype(np.int64)
            yield PointChunk(xyz, t_ns, np.full(len(t_ns), 40, np.uint8), round(0.02e9 * (k + 1)))

    return source


class _Each:
    def __init__(self, action: Callable[[int], None]) -> None:
        self.action = action
        self.frames = 0

    def write(self, sample: Sample, result: StepResult) -> None:
        self.frames += 1
        self.action(self.frames)


def _walk_line(duration_s: float) -> object:
    cfg = apply_overrides(get_scenario("walk-line"), particles=500)
    return live_config(cfg, duration_s=duration_s, scan_s=0.0)


def test_an_upright_vlp16_gives_one_frame_a_revolution() -> None:
    """walk-line's upright VLP-16 at 600 rpm, integration 0.1 s: frames run from one pass
    of 0° to the next, 0.1 s apart from device time 0 (azimuth 0.00°)."""
    port = _free_port()
    with EmulatedVelodyne(_wall(3.0), ip=LOOP, dest=(LOOP, port)):
        result = run_live(_walk_line(1.0), LiveSetup(f"velodyne://{LOOP}:{port}", "none", 1.0))  # type: ignore[arg-type]
    assert result.error is None
    log = result.run.log
    np.testing.assert_allclose(log.t, 0.1 * np.arange(1, 11), rtol=0, atol=5e-6)
    assert np.all(np.isfinite(log.latency_ms))
    assert np.all(log.latency_ms > 0)
    m = result.metrics()
    assert (m["packets_lost"], m["packets_malformed"], m["frames_dropped"]) == (0, 0, 0)
    assert m["lidar"] == f"velodyne://{LOOP}:{port}"


def test_a_silent_vlp16_ends_the_run_with_its_name() -> None:
    port = _free_port()
    with EmulatedVelodyne(_wall(3.0), ip=LOOP, dest=(LOOP, port)) as dev:

        def pause(k: int) -> None:
            if k == 3:
                dev.paused = True

        result = run_live(
            _walk_line(2.0),  # type: ignore[arg-type]
            LiveSetup(f"velodyne://{LOOP}:{port}", "none", 2.0),
            sinks=[_Each(pause)],
        )
    assert isinstance(result.error, DeviceError)
    assert f"VLP-16 on UDP {LOOP}:{port}: no data packet" in str(result.error)
    assert 3 <= len(result.run.log) <= 6


@pytest.mark.parametrize(
    ("sensor", "period", "revolutions"),
    [
        (SensorConfig(model="vlp16"), 0.1, True),
        (SensorConfig(model="vlp16", rpm=1200.0, integration_time_s=0.05), 0.05, True),
        (SensorConfig(model="vlp16", integration_time_s=0.05), 0.05, False),  # half a turn
        (SensorConfig(model="vlp16-side"), 0.1, False),  # seed 003: by time
        (SensorConfig(model="vlp16-side", rpm=300.0, integration_time_s=0.2), 0.2, False),
    ],
)
def test_the_scenarios_sensor_chooses_revolutions_or_integration_time(
    sensor: SensorConfig, period: float, revolutions: bool
) -> None:
    got, assembler = velodyne_frames(sensor)
    assert got == pytest.approx(period)
    assert isinstance(assembler, RevolutionAssembler) == revolutions
    assert (assembler is None) == (not revolutions)


def test_the_uri_and_host_ip_and_the_mount_reach_the_client() -> None:
    side = get_scenario("seed003-field").sensor
    client = open_point_stream("velodyne://2368", "127.0.0.5", side)
    assert isinstance(client, VelodyneClient)
    assert client.endpoint.bind_ip == "127.0.0.5"
    assert client.rotation is not None
    np.testing.assert_allclose(client.rotation @ [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], atol=1e-12)
    upright = open_point_stream("velodyne://2368", None, get_scenario("walk-line").sensor)
    assert isinstance(upright, VelodyneClient)
    assert upright.rotation is None
    with pytest.raises(ConfigError, match=r"host=127\.0\.0\.6 and the address 127\.0\.0\.5"):
        open_point_stream("velodyne://127.0.0.5:2368", "127.0.0.6")
    with pytest.raises(ConfigError, match=r"velodyne://\[IP:\]PORT \(VLP-16\)"):
        open_point_stream("velodine://2368")


def test_info_of_a_vlp16(capsys: pytest.CaptureFixture[str]) -> None:
    port = _free_port()
    with EmulatedVelodyne(_wall(3.0), ip=LOOP, dest=(LOOP, port)):
        assert run(["info", f"velodyne://{LOOP}:{port}"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[:5] == [
        f"listening: UDP {LOOP}:{port}",
        f"device: {LOOP}",
        "product: 0x22 (VLP-16 or Puck LITE)",
        "return mode: 0x37 (strongest)",
        "spin: 600 rpm",
    ]
    sampled = out[5]
    assert sampled.startswith("sampling 0.5 s: ")
    assert sampled.endswith(" points, 0 lost, 0 malformed")
    packets = int(sampled.split(": ")[1].split()[0])
    assert 0.5 * 753.5 * 0.9 <= packets <= 0.5 * 753.5 * 1.1 + 5


@pytest.mark.slow
def test_info_of_a_port_nobody_sends_to_is_one_error_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    port = _free_port()
    assert run(["info", f"velodyne://{LOOP}:{port}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: VLP-16 on UDP {LOOP}:{port}: no packet within 5 s")
    assert "\n" not in err
