"""Ctrl-C: one ``interrupted`` line, exit code 130, and what was done is kept.

The in-process tests send SIGINT from inside the run (the n-th frames.csv row
written), so they are deterministic; the subprocess tests send it from outside,
as a terminal does, at the whole process group.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from dronetrack.cli.main import run
from dronetrack.eval.log import TrackLog
from dronetrack.interrupt import handling_sigint, stop_requested, stoppable
from dronetrack.sinks import run_folder as runs

ROWS_BEFORE_INTERRUPT = 5


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _interrupt_after_rows(monkeypatch: pytest.MonkeyPatch, rows: int) -> None:
    """SIGINT to this process once frames.csv has ``rows`` rows."""
    write: Callable[[runs.FramesCsvWriter, TrackLog], None] = runs.FramesCsvWriter.write
    sent: list[bool] = []

    def write_then_interrupt(self: runs.FramesCsvWriter, log: TrackLog) -> None:
        write(self, log)
        if self.rows == rows and not sent:
            sent.append(True)
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(runs.FramesCsvWriter, "write", write_then_interrupt)


def _check_interrupted_run(folder: Path, err: str) -> None:
    lines = err.strip().splitlines()
    assert lines[-1].startswith("interrupted; kept"), err
    assert "Traceback" not in err
    frames = _rows(folder / "frames.csv")
    # The frame in hand when Ctrl-C came is finished and kept, then the loop stops.
    assert len(frames) == ROWS_BEFORE_INTERRUPT
    metrics = json.loads((folder / "metrics.json").read_text())
    assert metrics["interrupted"] is True
    assert metrics["frames"] == len(frames)
    assert (folder / "config.toml").exists()


def test_ctrl_c_stops_simulate_after_the_frame_and_keeps_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _interrupt_after_rows(monkeypatch, ROWS_BEFORE_INTERRUPT)
    out = tmp_path / "run"
    assert run(["simulate", "--duration", "30", "--out", str(out)]) == 130
    _check_interrupted_run(out, capsys.readouterr().err)


@pytest.mark.slow
def test_ctrl_c_stops_track_after_the_frame_and_keeps_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / "flight.bag"
    assert run(["record", "--duration", "3", "--out", str(bag)]) == 0
    _interrupt_after_rows(monkeypatch, ROWS_BEFORE_INTERRUPT)
    out = tmp_path / "run"
    assert run(["track", str(bag), "--out", str(out)]) == 130
    _check_interrupted_run(out, capsys.readouterr().err)
    assert (out / "commands.csv").exists()


def test_ctrl_c_outside_a_loop_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C while loading or compiling raises KeyboardInterrupt at once; numba's
    compiler can wrap it in a SystemError: both end as one line and exit 130."""
    import dronetrack.config.scenarios as scenarios

    def interrupted(name: str) -> None:
        raise KeyboardInterrupt

    def wrapped(name: str) -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as err:
            raise SystemError("<numba dispatcher> returned a result with an exception set") from err

    for fake in (interrupted, wrapped):
        monkeypatch.setattr(scenarios, "get_scenario", fake)
        assert run(["simulate", "--duration", "1"]) == 130
        captured = capsys.readouterr()
        assert captured.err == "interrupted\n"
        assert captured.out == ""


def test_a_system_error_of_another_cause_is_not_taken_for_an_interrupt(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import dronetrack.config.scenarios as scenarios

    def broken(name: str) -> None:
        raise SystemError("a real bug")

    monkeypatch.setattr(scenarios, "get_scenario", broken)
    with pytest.raises(SystemError, match="a real bug"):
        run(["simulate", "--duration", "1"])


def test_first_ctrl_c_in_a_loop_sets_the_flag_a_second_raises() -> None:
    # The handler the process had (the default one, or SIG_IGN when started in the
    # background by a shell without job control) comes back afterwards.
    before = signal.getsignal(signal.SIGINT)
    with handling_sigint(), stoppable():
        assert not stop_requested()
        signal.raise_signal(signal.SIGINT)
        assert stop_requested()
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
        # Outside a loop the flag is not what stops anything: Ctrl-C raises.
    with handling_sigint(), pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)
    assert not stop_requested()  # cleared with the handler
    assert signal.getsignal(signal.SIGINT) is before


def _wait_for(predicate: Callable[[], bool], proc: subprocess.Popen[str], limit_s: float) -> None:
    deadline = time.monotonic() + limit_s
    while not predicate():
        if proc.poll() is not None:
            pytest.fail(f"ended before the interrupt: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"not ready after {limit_s} s")
        time.sleep(0.2)


def _line_count(path: Path) -> int:
    return len(path.read_text().splitlines()) if path.exists() else 0


def _dronetrack(*args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.Popen(
        [sys.executable, "-m", "dronetrack", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,  # its own process group, as a terminal's job
    )


def _python(script: str) -> subprocess.CompletedProcess[str]:
    """``script`` run by a Python of its own (its signal handlers and exit handlers are
    its own), its output captured."""
    return subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )


def test_a_ctrl_c_once_the_command_is_done_exits_at_once_with_its_code() -> None:
    """While the interpreter shuts down after a command (its threads joined, its DDS
    participants closed), a Ctrl-C exits at once with the command's code, the output
    flushed, rather than raising KeyboardInterrupt there and dying of the signal."""
    script = (
        "import os, signal, sys, time\n"
        "from dronetrack.interrupt import exit_on_sigint\n"
        "exit_on_sigint(3)\n"
        "print('done', end='')\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(30)\n"
    )
    done = _python(script)
    assert done.returncode == 3, done.stderr
    assert done.stdout == "done"
    assert "Traceback" not in done.stderr


def test_a_ctrl_c_during_the_interpreters_finalization_is_ignored() -> None:
    """From the exit handlers on SIGINT is ignored: the finalization after them puts a
    Python handler back to the default, under which a Ctrl-C while the C libraries'
    exit handlers run kills the process by the signal.  An exit handler registered
    before ``exit_on_sigint`` runs after its own (last in, first out) and sees it."""
    script = (
        "import atexit, signal, sys\n"
        "atexit.register(lambda: sys.stdout.write("
        "str(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)))\n"
        "from dronetrack.interrupt import exit_on_sigint\n"
        "exit_on_sigint(3)\n"
        "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN, end=' ')\n"
    )
    done = _python(script)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "False True"  # the command's handler, then ignored at exit


def test_a_ctrl_c_just_after_the_command_exits_as_interrupted() -> None:
    """A Ctrl-C that lands after the command's own handling has ended, before the
    shutdown's (``exit_on_sigint`` with the command's code), exits with 130: it does
    not raise ``KeyboardInterrupt`` out of ``main`` and die of the signal."""
    script = (
        "import os, signal, sys\n"
        "import dronetrack.cli.main as cli\n"
        "def done(argv):\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    return 0\n"
        "cli.run = done\n"
        "sys.argv = ['dronetrack']\n"
        "cli.main()\n"
    )
    done = _python(script)
    assert done.returncode == 130, done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.slow
def test_ctrl_c_from_a_terminal_stops_simulate(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _dronetrack("simulate", "--duration", "120", "--out", str(out))
    _wait_for(lambda: _line_count(out / "frames.csv") > 10, proc, 300)
    seen = _line_count(out / "frames.csv") - 1
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("interrupted; kept"), err
    assert "Traceback" not in err
    kept = _rows(out / "frames.csv")
    assert seen <= len(kept) < 1200  # stopped long before the 120 s flight ended
    assert json.loads((out / "metrics.json").read_text())["frames"] == len(kept)


@pytest.mark.slow
def test_ctrl_c_from_a_terminal_stops_a_sweep_and_it_resumes(tmp_path: Path) -> None:
    """Every line of results.jsonl stays whole, the interrupted runs are not recorded
    as failed, the workers stop, and the same command then finishes the grid."""
    grid = tmp_path / "grid.toml"
    grid.write_text(
        'scenario = "default"\nduration = 4\nruns = 1\n\n[grid]\nparticles = [500, 1000, 1500]\n'
        'tracker = ["pf-delta", "pf-cv"]\n'
    )
    out = tmp_path / "sweep"
    results = out / "results.jsonl"
    proc = _dronetrack("sweep", str(grid), "--workers", "2", "--out", str(out))
    _wait_for(lambda: _line_count(results) >= 1, proc, 300)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("interrupted;"), err
    assert "Traceback" not in err
    rows = [json.loads(line) for line in results.read_text().splitlines()]
    assert 1 <= len(rows) < 6
    assert not [r for r in rows if "error" in r]
    # No worker outlives the sweep: the group has no process left.
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        time.sleep(0.2)
    else:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("worker processes outlived the interrupted sweep")
    again = _dronetrack("sweep", str(grid), "--workers", "2", "--out", str(out))
    _, err = again.communicate(timeout=600)
    assert again.returncode == 0, err
    keys = [json.loads(line)["key"] for line in results.read_text().splitlines()]
    assert len(keys) == 6
    assert len(set(keys)) == 6


def test_ctrl_c_stops_record_and_the_bag_reads_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The recording is closed properly after the frame in hand: info and track read it."""
    from dronetrack.sinks.bag_writer import RecordingWriter

    frame = RecordingWriter.frame
    written: list[int] = []

    def frame_then_interrupt(self: RecordingWriter, *args: object, **kwargs: object) -> None:
        frame(self, *args, **kwargs)  # type: ignore[arg-type]
        written.append(1)
        if len(written) == 40:
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(RecordingWriter, "frame", frame_then_interrupt)
    bag = tmp_path / "flight.bag"
    assert run(["record", "--duration", "30", "--out", str(bag)]) == 130
    err = capsys.readouterr().err
    assert err.strip().splitlines()[-1].startswith(f"interrupted; kept {bag}"), err
    assert "40 frames" in err
    monkeypatch.undo()
    assert run(["info", str(bag)]) == 0
    listing = capsys.readouterr().out
    lidar = [line for line in listing.splitlines() if "/livox/lidar" in line]
    assert lidar[0].split("│")[3].strip() == "40"
