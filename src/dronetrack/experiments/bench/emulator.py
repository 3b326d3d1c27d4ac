"""``dronetrack emulate`` in its own process for the live benchmarks: a loopback address
of its own, the URIs it prints, and the scenario with the turret asked for (the
Dynamixel servos of its own preset, or a FLIR PTU-E46)."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from dronetrack.config.scenarios import get_scenario
from dronetrack.config.spinning import SPINNING
from dronetrack.errors import ConfigError, DeviceError

__all__ = [
    "CHAINS",
    "EMULATOR_START_S",
    "EMULATOR_STOP_S",
    "TURRETS",
    "EmulatorProcess",
    "emulator_process",
    "scenario_with_turret",
]

EMULATOR_START_S = 120.0  # emulate's start, compiling the simulator's kernels if not cached
EMULATOR_STOP_S = 10.0
CHAINS = ("livox", "ros2")  # the Livox SDK 1 and turret protocols, or ROS 2 over DDS


@dataclass(frozen=True, slots=True)
class EmulatorProcess:
    """A running ``dronetrack emulate``: the URIs to open, its truth file, and the ROS 2
    domain (None for the Livox chain)."""

    proc: subprocess.Popen[bytes]
    lidar: str  # livox://IP with free host ports, velodyne://IP:2368 or ros2:///livox/lidar
    turret: str  # dynamixel://LINK, ptu://LINK or ros2:///turret, as the emulator printed it
    truth: Path
    ros_domain_id: int | None = None


def _ros_domain() -> int:
    """A ROS 2 domain of this process's own (1-100), so that no other run is met."""
    return 1 + os.getpid() % 100


def _loopback_ip() -> str:
    """A loopback address of this process's own (127.0.1.x), so that the emulator's
    fixed device port meets no other run's."""
    return f"127.0.1.{1 + os.getpid() % 250}"


def _read_lines(proc: subprocess.Popen[bytes], count: int, timeout_s: float) -> bytes:
    """The first ``count`` lines ``proc`` prints (fewer if it ends or the time is up)."""
    assert proc.stdout is not None
    out = b""
    deadline = time.monotonic() + timeout_s
    while out.count(b"\n") < count and time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.5)
        if ready:
            got = os.read(proc.stdout.fileno(), 4096)
            if not got:
                break
            out += got
    return out


@contextmanager
def emulator_process(
    workdir: Path,
    scenario: str = "default",
    seed: int = 0,
    flight_s: float = 20.0,
    ptu_baud: int = 9600,
    chain: str = "livox",
) -> Iterator[EmulatorProcess]:
    """``dronetrack emulate SCENARIO --seed SEED --duration FLIGHT_S`` in its own
    process (``chain`` "ros2": with ``--ros2`` on a domain of this process's own), once
    it has printed its two addresses; stopped (SIGTERM, then killed) on leaving.  Its
    messages go to ``workdir/emulate.log``.  DeviceError if it does not start within
    ``EMULATOR_START_S``."""
    if chain not in CHAINS:
        raise ConfigError(f"the live chain is one of {', '.join(CHAINS)}, not {chain!r}")
    ip = _loopback_ip()
    link, truth, log_path = workdir / "ttyDXL", workdir / "truth.csv", workdir / "emulate.log"
    args = [scenario, "--seed", str(seed), "--duration", f"{flight_s:g}", "--truth", str(truth)]
    domain = _ros_domain() if chain == "ros2" else None
    velodyne = domain is None and get_scenario(scenario).sensor.model in SPINNING
    if domain is not None:
        args += ["--ros2", "--ros-domain-id", str(domain)]
    else:
        args += ["--lidar-ip", ip, "--serial-link", str(link), "--ptu-baud", str(ptu_baud)]
    if velodyne:  # a VLP-16 sends to port 2368 of the emulator's own address
        args += ["--lidar-dest", f"{ip}:2368"]
    with log_path.open("wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "dronetrack", "emulate", *args],
            stdout=subprocess.PIPE,
            stderr=log,
        )
        try:
            printed = _read_lines(proc, 2, EMULATOR_START_S)
            if printed.count(b"\n") < 2:
                raise DeviceError(
                    f"dronetrack emulate did not start (exit {proc.poll()}); see {log_path}"
                )
            lidar, turret = (line.split()[1] for line in printed.decode().splitlines()[:2])
            if domain is None and not velodyne:
                # host ports 0: free ones, so that no other live run on this machine is met
                lidar = f"livox://{ip}?cmd_port=0&data_port=0&broadcast_port=0"
            yield EmulatorProcess(proc, lidar, turret, truth, domain)
        finally:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=EMULATOR_STOP_S)
                except subprocess.TimeoutExpired:
                    proc.kill()
            proc.wait(timeout=EMULATOR_STOP_S)
            if proc.stdout is not None:
                proc.stdout.close()


TURRETS = ("dynamixel", "ptu")  # the emulated turrets a live benchmark can drive


def scenario_with_turret(scenario: str, turret: str, workdir: Path) -> str:
    """``scenario`` with the turret ``turret`` drives: as it is for the Dynamixel (its
    own preset), or written to a file in ``workdir`` with the PTU-E46's preset."""
    if turret not in TURRETS:
        raise ConfigError(f"a live benchmark drives {' or '.join(TURRETS)}, not {turret!r}")
    if turret == "dynamixel":
        return scenario
    path = workdir / "scenario-ptu.toml"
    text = f'base = "{scenario}"\nname = "{scenario}-ptu"\n\n[turret]\nmodel = "ptu-e46"\n'
    path.write_text(text)
    return str(path)
