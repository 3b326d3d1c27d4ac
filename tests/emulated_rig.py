"""``dronetrack emulate`` in a subprocess for the tests that drive it: started on a
loopback address of its own (127.0.0.x), so its fixed device port 65000 (a VLP-16: the
host's port 2368 there) meets no other test's, and killed after if still running; every
wait is bounded."""

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

START_S = 120.0  # the command's start, with the simulator's kernels compiled once


@dataclass
class Emulator:
    proc: subprocess.Popen[bytes]
    ip: str
    link: Path
    truth: Path
    lines: list[str]

    @property
    def turret(self) -> str:
        """The turret URI the emulator printed (``turret: URI  (…)``)."""
        return self.lines[1].split()[1]


@contextmanager
def emulator(
    tmp_path: Path, scenario: str, *options: str, velodyne: bool = False
) -> Iterator[Emulator]:
    """``dronetrack emulate SCENARIO OPTIONS`` with a serial link and a truth file in
    ``tmp_path`` (with ``--ros2`` among the options: the truth file only), once it has
    printed its two addresses.  A VLP-16 (``velodyne``) sends to port 2368 of the
    emulator's own address, where the host listens."""
    ip = f"127.0.0.{20 + os.getpid() % 200}"
    link, truth = tmp_path / "ttyDXL", tmp_path / "truth.csv"
    args = [scenario, *options, "--truth", str(truth)]
    if "--ros2" not in options:
        args += ["--lidar-ip", ip, "--serial-link", str(link)]
    if velodyne:
        args += ["--lidar-dest", f"{ip}:2368"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "dronetrack", "emulate", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None
        out = b""
        deadline = time.monotonic() + START_S
        while out.count(b"\n") < 2 and time.monotonic() < deadline:
            ready, _, _ = select.select([proc.stdout], [], [], 0.5)
            if ready:
                got = os.read(proc.stdout.fileno(), 4096)
                if not got:
                    break
                out += got
        lines = out.decode().splitlines()
        assert len(lines) == 2, (lines, proc.poll())
        yield Emulator(proc, ip, link, truth, lines)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)
        for pipe in (proc.stdout, proc.stderr):
            if pipe is not None:
                pipe.close()
