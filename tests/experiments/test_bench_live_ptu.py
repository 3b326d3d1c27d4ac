"""``dronetrack bench --live --turret ptu``: the live latency run with the emulated FLIR
PTU-E46 on a quick run (a smoke test, no soak), and its options' errors.  Latency is
reported by the benchmark, never asserted here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rich.console import Console

from dronetrack.cli.bench import live_table
from dronetrack.cli.main import run
from dronetrack.errors import ConfigError
from dronetrack.experiments.bench import LiveSettings


@pytest.mark.slow
def test_quick_live_bench_with_the_ptu(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["bench", "--live", "--quick", "--soak-s", "0", "--turret", "ptu"]
    assert run([*args, "--ptu-baud", "38400", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    data = json.loads((tmp_path / "bench_live.json").read_text())
    assert data["settings"]["turret"] == "ptu"
    assert data["settings"]["ptu_baud"] == 38400
    lat = data["live_latency"]
    assert lat["turret"].startswith("ptu://")
    assert lat["turret"].endswith("?baud=38400")
    assert 15 <= lat["frames"] + lat["frames_dropped"] <= 21
    assert 0 < lat["latency_ms_p50"] <= lat["latency_ms_p99"]
    assert data["live_soak"] is None
    assert out.strip().splitlines()[-1] == str(tmp_path / "bench_live.json")
    wide = Console(width=200, record=True)
    wide.print(live_table(data, tmp_path / "bench_live.json"))
    assert "latency run: 2 s of flight, FLIR PTU-E46 at 38400 baud" in wide.export_text()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--turret", "ptu"], "go with --live"),
        (["--live", "--ptu-baud", "38400"], "--ptu-baud goes with --turret ptu"),
        (["--live", "--turret", "pantilt"], "drives dynamixel or ptu, not 'pantilt'"),
        (["--live", "--turret", "ptu", "--ptu-baud", "1000"], "baud 1000 is not a standard"),
    ],
)
def test_bad_ptu_bench_options_exit_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert run(["bench", "--out", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert "\n" not in err


def test_the_settings_name_the_turret() -> None:
    assert LiveSettings(turret="ptu").checked().ptu_baud == 9600
    with pytest.raises(ConfigError, match="not 'servo'"):
        LiveSettings(turret="servo").checked()
