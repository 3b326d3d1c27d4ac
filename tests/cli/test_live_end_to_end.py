"""The whole live chain on one machine: ``dronetrack emulate`` (the simulator in real time
behind an emulated Livox LiDAR on UDP and two emulated XM430 servos on a pseudo-terminal)
in its own process, and ``dronetrack live`` against it through the real protocols, for
20 s of flight (and, first, a short run with ``dronetrack info`` of the same LiDAR
started beside it: refused in one line, the live run untouched, both processes ending
by themselves with exit code 0):

- SDK 1: an Avia, the ``default`` flight after its 10 s background scan, with the
  sensor's random false alarms off (``emulated_rig.without_false_alarms``);
- SDK 2: a Mid-360, the ``mid360-aggressive`` flight (seed 002's sensor and F550 in
  aggressive flight) after its 2 s scan; the test takes 27.5-28.1 s here (3 runs at a
  load average of 1.4-1.7);
- a VLP-16 (``velodyne://``), upright, one frame a revolution: seed 003's ``walk-line``
  (a board walked towards the sensor) after its 10 s scan, on seed 003's PTU-E46
  (``ptu://``, 9600 baud), tracking;
- a VLP-16 on its side, frames of the integration time: ``seed003-field`` (a Spyder X4
  flying laps, the PTU sweeping ±90° at 30°/s).
  Both VLP-16 scenarios have the sensor's random false alarms off too: ``emulate`` draws
  its returns in 20 ms slices and ``simulate`` in 0.1 s frames, so their false alarms
  fall differently, and on ``seed003-field`` (an EKF on single returns) one false
  return beside the drone sent the live run's filter astray (8.0 % against 35.0 %,
  measured with the WidowX before the PTU emulator); with them the upright run gave
  81.0 % and 66.5 % against 84.0 %.  Without them (measured with the PTU, 3 runs each
  at a load average of 1.0): ``walk-line`` live 84.0 % every time, simulate 84.0 %;
  ``seed003-field`` live 32.5, 33.0 and 31.5 %, simulate 31.5 %.

Against ``dronetrack simulate`` of the same seed and flight time, the live run must cover
the drone within 10 points (the issue's bound: the two differ only in real-time
effects, the turret's command timing and the servos' reads), and lose no packet and
drop no frame.  Measured on seed 0 at a load average of 1-2: the Avia live 95.0 % in 7 of
7 runs, simulate 95.0 % (with false alarms: 95.0 % or 82.5-83.0 %, the latter in 1 of 9
runs here and 4 of 7 earlier, when a false alarm in the scan fell by the drone's
take-off spot); the Mid-360 live 93.5 %, 96.0 %, 92.0 %, 100.0 %, simulate 100.0 %.  With 15 s
of the Mid-360's flight one run of eleven fell 10.7 points below simulate, hence 20 s.

Both run in real time and feel the machine's load: with a load average of 4-6 from other
processes, before the servos' reads were polled, they failed in some runs on a servo's
status packet later than the DYNAMIXEL SDK's timeout (about 34 ms); since, one Avia run
of eight, at a load average of 2.5, ended on its points arriving 1 s late."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dronetrack.cli.main import run
from emulated_rig import (
    FLIGHT_S,
    assert_tracks_as_simulated,
    emulator,
    live_then_simulate,
    metrics_of,
    without_false_alarms,
)

# emulate ends 2 s after the scenario's end, when live (which stops at the flight's end)
# has closed; simulate runs in between
EMULATOR_END_S = 15.0


@pytest.mark.slow
def test_info_beside_a_running_live_is_refused_and_both_end_by_themselves(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "short.toml"
    scenario.write_text('base = "default"\n[pipeline.background]\nscan_s = 0.5\n')
    flight = "2"
    out = tmp_path / "live"
    with emulator(tmp_path, str(scenario), "--seed", "0", "--duration", flight) as emu:
        cmd = [sys.executable, "-m", "dronetrack", "live", str(scenario), "--lidar",
               f"livox://{emu.ip}", "--turret", emu.turret, "--duration", flight, "--out",
               str(out)]  # fmt: skip
        live = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            frames = out / "frames.csv"
            deadline = time.monotonic() + 60.0
            while time.monotonic() < deadline and live.poll() is None:
                if frames.exists() and len(frames.read_text().splitlines()) > 3:
                    break  # tracking
                time.sleep(0.05)
            assert live.poll() is None, live.communicate()[1]
            code = run(["info", f"livox://{emu.ip}"])
            _, live_err = live.communicate(timeout=60.0)
        finally:
            if live.poll() is None:
                live.kill()
                live.wait(timeout=5.0)
        emulate_rc = emu.proc.wait(timeout=EMULATOR_END_S)
        emulate_err = emu.proc.stderr.read().decode() if emu.proc.stderr else ""
    info = capsys.readouterr()
    assert code == 2
    assert info.out == ""
    assert re.fullmatch(
        rf"error: Livox SDK 1 device at {re.escape(emu.ip)}: UDP port 55501 \(commands\) is in use "
        r"on this host, most likely by another dronetrack live or info on this LiDAR; a "
        r"second LiDAR needs its own \(the URI's cmd_port=\)\n",
        info.err,
    )
    assert live.returncode == 0, live_err
    metrics = metrics_of(out)
    assert "error" not in metrics
    assert metrics["packets_lost"] == 0
    assert len((out / "frames.csv").read_text().splitlines()) == 1 + 20  # 2 s of 10 Hz
    assert emulate_rc == 0, emulate_err
    assert emulate_err.count("sampling started") == 1  # info started nothing


@pytest.mark.slow
def test_live_against_the_emulated_rig_tracks_as_the_simulation_does(tmp_path: Path) -> None:
    scenario = without_false_alarms(tmp_path, "default")
    with emulator(tmp_path, scenario, "--seed", "0", "--duration", FLIGHT_S) as emu:
        lidar, turret = f"livox://{emu.ip}", f"dynamixel://{emu.link}"
        got, want = live_then_simulate(tmp_path, emu, scenario, lidar, turret)
        assert emu.proc.wait(timeout=EMULATOR_END_S) == 0  # the scenario streamed, it ends
    assert got["lidar"] == lidar
    assert_tracks_as_simulated(got, want)


@pytest.mark.slow
def test_live_against_an_emulated_mid360_over_sdk2_tracks_as_the_simulation_does(
    tmp_path: Path,
) -> None:
    scenario = "mid360-aggressive"
    with emulator(tmp_path, scenario, "--seed", "0", "--duration", FLIGHT_S) as emu:
        assert emu.lines[0].startswith(f"lidar: livox2://{emu.ip}  (Livox Mid-360")
        lidar, turret = f"livox2://{emu.ip}", f"dynamixel://{emu.link}"
        got, want = live_then_simulate(tmp_path, emu, scenario, lidar, turret)
        assert emu.proc.wait(timeout=EMULATOR_END_S) == 0
    assert got["lidar"] == lidar
    assert_tracks_as_simulated(got, want)


def _against_simulate(tmp_path: Path, scenario: str, uri_of: str) -> None:
    """``live`` of ``scenario`` against its emulated VLP-16 and PTU-E46, then ``simulate``
    of it, both with seed 0 for 20 s of flight; the live run's bars as above."""
    with emulator(tmp_path, scenario, "--seed", "0", "--duration", FLIGHT_S, velodyne=True) as emu:
        uri = f"velodyne://{emu.ip}:2368"
        assert emu.lines[0].startswith(f"lidar: {uri}  ({uri_of}")
        assert emu.turret.startswith("ptu://")
        got, want = live_then_simulate(tmp_path, emu, scenario, uri, emu.turret)
        assert emu.proc.wait(timeout=EMULATOR_END_S) == 0
    assert got["lidar"] == uri
    assert_tracks_as_simulated(got, want)


@pytest.mark.slow
def test_live_against_an_emulated_upright_vlp16_tracks_as_the_simulation_does(
    tmp_path: Path,
) -> None:
    scenario = without_false_alarms(tmp_path, "walk-line")
    _against_simulate(tmp_path, scenario, "Velodyne VLP-16, UDP")


@pytest.mark.slow
def test_live_against_an_emulated_vlp16_on_its_side_tracks_as_the_simulation_does(
    tmp_path: Path,
) -> None:
    scenario = without_false_alarms(tmp_path, "seed003-field")
    _against_simulate(tmp_path, scenario, "Velodyne VLP-16 on its side, UDP")
