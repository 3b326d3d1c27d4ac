"""``dronetrack sweep`` end to end: local processes, a Dask cluster, a killed worker,
resuming, and the report."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dronetrack.cli.main import run
from dronetrack.experiments.sweep.store import read_results

# Two particle counts × two σ_pos on a short run of the default scenario (a 1 s scan).
GRID = """scenario = "default"
duration = {duration}
runs = {runs}

[grid]
particles = [500, 1000]
"track.sigma_pos" = [0.4, 0.5]
"pipeline.background.scan_s" = [1.0]
"""


def _grid(tmp_path: Path, duration: float = 1.0, runs: int = 1) -> Path:
    path = tmp_path / "grid.toml"
    path.write_text(GRID.format(duration=duration, runs=runs))
    return path


def _check_results(out: Path, n: int) -> list[dict[str, object]]:
    rows = list(read_results(out / "results.jsonl"))
    assert len(rows) == n
    assert len({r["key"] for r in rows}) == n
    for r in rows:
        assert "error" not in r, r.get("error")
        metrics = r["metrics"]
        assert isinstance(metrics, dict)
        assert metrics["frames"] > 0
        assert "coverage_pct" in metrics
    return rows


@pytest.mark.slow
def test_local_sweep_resumes_and_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    grid, out = _grid(tmp_path), tmp_path / "out"
    assert run(["sweep", str(grid), "--workers", "2", "--out", str(out)]) == 0
    rows = _check_results(out, 4)
    assert {(r["params"]["particles"], r["params"]["track.sigma_pos"]) for r in rows} == {
        (500, 0.4),
        (500, 0.5),
        (1000, 0.4),
        (1000, 0.5),
    }
    # The σ the run used and eq. (11)'s are in every line (for the report's colours).
    assert all(r["sigma"]["sigma_pos"] == r["params"]["track.sigma_pos"] for r in rows)
    assert all(r["eq11"]["sigma_pos"] == pytest.approx(0.5) for r in rows)
    before = (out / "results.jsonl").read_bytes()
    capsys.readouterr()
    # A finished sweep adds nothing when run again.
    assert run(["sweep", str(grid), "--workers", "2", "--out", str(out)]) == 0
    assert "0 done now, 4 done before" in capsys.readouterr().out
    assert (out / "results.jsonl").read_bytes() == before
    # Two seeds per combination: only the new runs are run.
    assert run(["sweep", str(_grid(tmp_path, runs=2)), "--workers", "2", "--out", str(out)]) == 0
    assert "4 done now, 4 done before" in capsys.readouterr().out
    _check_results(out, 8)
    assert (out / "results.jsonl").read_bytes().startswith(before)
    assert run(["sweep-report", str(out)]) == 0
    report = capsys.readouterr().out
    assert "4 combinations" in report
    for name in ("coverage_vs_distance.png", "best.csv", "report.md"):
        assert (out / name).exists()


@pytest.mark.slow
def test_sweep_on_a_dask_cluster(tmp_path: Path) -> None:
    from distributed import LocalCluster

    out = tmp_path / "out"
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        assert run(["sweep", str(_grid(tmp_path)), "--scheduler", address, "--out", str(out)]) == 0
    rows = _check_results(out, 4)
    # The runs ran in the cluster's worker processes, not here.
    assert os.getpid() not in {r["pid"] for r in rows}


def _descendants(pid: int) -> dict[int, int]:
    """Every process below ``pid``: {pid: parent pid} (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        # pid (comm) state ppid ...; comm may hold spaces, so split after the last ')'
        parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    below: dict[int, int] = {}
    frontier = [pid]
    while frontier:
        p = frontier.pop()
        for child, parent in parents.items():
            if parent == p and child not in below:
                below[child] = parent
                frontier.append(child)
    return below


@pytest.mark.slow
def test_a_killed_worker_loses_no_finished_result(tmp_path: Path) -> None:
    grid, out = _grid(tmp_path, duration=2.0, runs=2), tmp_path / "out"
    results = out / "results.jsonl"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "dronetrack",
            "sweep",
            str(grid),
            "--workers",
            "2",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while not (results.exists() and results.read_text().count("\n") >= 1):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no result within 2 minutes"
            time.sleep(0.05)
        finished = results.read_text()
        # The pool's workers are the sweep's grandchildren (children of the forkserver).
        tree = _descendants(proc.pid)
        workers = [p for p, parent in tree.items() if parent != proc.pid]
        assert workers
        os.kill(workers[0], signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert "8 done now" in stdout
    # Everything that was finished when the worker died is still there, word for word,
    # and every run is there exactly once.
    assert results.read_text().startswith(finished)
    _check_results(out, 8)
    assert "a worker died" in stderr


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["sweep", "{tmp}/missing.toml"], "grid file not found"),
        (["sweep", "{grid}", "--workers", "2", "--scheduler", "tcp://x:1"], "not both"),
        (
            ["sweep", "{grid}", "--scheduler", "tcp://127.0.0.1:1"],
            "cannot reach the Dask scheduler",
        ),
        (["sweep", "{bad}"], "unknown key 'sigma_posx'"),
        (["sweep-report", "{tmp}"], "no results.jsonl"),
    ],
)
@pytest.mark.slow
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    grid = _grid(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text('[grid]\n"track.sigma_posx" = [1.0]\n')
    filled = [a.format(tmp=tmp_path, grid=grid, bad=bad) for a in argv]
    assert run([*filled, "--out", str(tmp_path / "o")] if argv[0] == "sweep" else filled) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert len(err.splitlines()) == 1


def test_missing_dask_gives_the_install_hint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    argv = ["sweep", str(_grid(tmp_path)), "--scheduler", "tcp://127.0.0.1:8786"]
    assert run([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: --scheduler needs dask.distributed: pip install 'dronetrack[dask]'"


@pytest.mark.slow
def test_an_interrupted_sweep_resumes_where_it_stopped(tmp_path: Path) -> None:
    """The sweep itself is killed after its first result; running it again finishes the
    grid without repeating or losing anything."""
    grid, out = _grid(tmp_path, duration=2.0, runs=2), tmp_path / "out"
    results = out / "results.jsonl"
    argv = [sys.executable, "-m", "dronetrack", "sweep", str(grid), "--workers", "2"]
    proc = subprocess.Popen(
        [*argv, "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 120
        while not (results.exists() and results.read_text().count("\n") >= 1):
            assert proc.poll() is None
            assert time.monotonic() < deadline, "no result within 2 minutes"
            time.sleep(0.05)
        for pid in _descendants(proc.pid):
            os.kill(pid, signal.SIGKILL)
        proc.kill()
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    first = results.read_text()
    n_first = len(list(read_results(results)))
    assert 1 <= n_first < 8
    done = subprocess.run([*argv, "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"{8 - n_first} done now, {n_first} done before" in done.stdout
    assert results.read_text().startswith(first)
    _check_results(out, 8)


@pytest.mark.slow
def test_a_sweep_over_a_recording_replays_it(tmp_path: Path) -> None:
    bag = tmp_path / "flight.bag"
    assert run(["record", "--out", str(bag), "--duration", "2", "--seed", "3"]) == 0
    grid = tmp_path / "grid.toml"
    grid.write_text('recording = "flight.bag"\n[grid]\ntracker = ["pf-delta", "ekf-dogru"]\n')
    out = tmp_path / "out"
    assert run(["sweep", str(grid), "--workers", "1", "--out", str(out)]) == 0
    rows = _check_results(out, 2)
    assert {r["tracker"] for r in rows} == {"pf-delta", "ekf-dogru"}
    assert all(r["source"] == {"recording": str(bag)} for r in rows)
    # The replay covers the recording's 12 s: a 10 s scan, then 2 s of tracking.
    assert all(r["metrics"]["frames"] == 20 for r in rows)
