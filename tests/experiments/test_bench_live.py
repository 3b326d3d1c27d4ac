"""``dronetrack bench --live``: the live benchmarks' code path on a quick run (a smoke
test: ``dronetrack emulate`` in its own process and ``live`` against it for a few
seconds), bench_live.json's structure, the memory figures, and bad input.

Latency and memory growth are reported by the benchmark, never asserted here: the
quick run only checks that every figure is there and sane."""

from __future__ import annotations

import json
import math
import mmap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.errors import ConfigError
from dronetrack.experiments.bench import (
    LIVE_QUICK,
    LIVE_TARGETS,
    LiveSettings,
    live_request,
    resident_mb,
    rss_growth_pct,
)

pytest.importorskip("dynamixel_sdk")


def _count(value: Any) -> bool:
    return isinstance(value, int) and value >= 0


@pytest.mark.slow
def test_quick_live_bench_writes_every_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["bench", "--live", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    path = tmp_path / "bench_live.json"
    assert out.strip().splitlines()[-1] == str(path)
    assert not (tmp_path / "bench.json").exists()
    data = json.loads(path.read_text())
    assert data["settings"]["quick"] is True
    assert data["settings"]["latency_s"] == LIVE_QUICK.latency_s

    lat = data["live_latency"]
    # 2 s of flight at 10 Hz after the scan: every frame logged or dropped
    assert 15 <= lat["frames"] + lat["frames_dropped"] <= 21
    assert 0 < lat["latency_ms_p50"] <= lat["latency_ms_p99"]
    for key in ("frames_dropped", "packets_lost", "packets_malformed", "turret_reads_missed"):
        assert _count(lat[key]), key
    assert lat["turret"].startswith("dynamixel://")
    assert lat["met"] == (lat["latency_ms_p99"] <= 20.0)

    soak = data["live_soak"]
    samples = np.array(soak["rss_samples"])
    # a sample every 0.5 s through the 0.5 s scan and the 4 s flight, from the devices' answer
    assert len(samples) >= 7
    assert np.all(np.diff(samples[:, 0]) > 0)
    assert np.all(samples[:, 1] > 10.0)  # MB: numpy, numba and the pipeline are loaded
    assert soak["rss_mb_max"] == max(mb for t, mb in soak["rss_samples"] if t >= 1.0)
    assert soak["rss_growth_pct"] == pytest.approx(
        100.0 * (soak["rss_mb_max"] - soak["rss_mb_warm"]) / soak["rss_mb_warm"]
    )
    assert soak["coverage_pct"] is None  # a soak runs as a rig does, without truth

    targets = data["targets"]
    assert set(targets) == {t.key for t in LIVE_TARGETS if t.path[0] != "live_latency_sapient"}
    assert data["live_latency_sapient"] is None  # without --sapient
    assert targets["live_latency.latency_ms_p99"]["value"] == lat["latency_ms_p99"]
    assert targets["live_soak.rss_growth_pct"]["value"] == soak["rss_growth_pct"]
    for target in targets.values():
        assert math.isfinite(target["value"])
        assert target["met"] == (target["value"] <= target["limit"])
    assert out.count("met") + out.count("MISSED") >= len(targets)


@pytest.mark.slow
def test_quick_live_bench_with_sapient_times_its_reports_and_a_restart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The latency run again with a SAPIENT edge node, its fusion node killed half-way
    and started again: the figures are there and sane (their targets are the
    benchmark's business)."""
    pytest.importorskip("google.protobuf")
    args = ["bench", "--live", "--quick", "--sapient", "--soak-s", "0", "--latency-s", "6"]
    assert run([*args, "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "bench_live.json").read_text())
    c2 = data["live_latency_sapient"]
    assert c2["frames"] + c2["frames_dropped"] >= 55  # 6 s of flight at 10 Hz
    assert c2["sapient_sent"] > 0
    assert c2["sapient_connects"] == 2  # once, then again after the kill
    assert 0.0 < c2["sapient_reconnect_s"] < 30.0
    assert 0.0 < c2["sapient_first_report_ms_median"] <= c2["sapient_first_report_ms_max"]
    assert c2["p99_growth_ms"] == pytest.approx(
        c2["latency_ms_p99"] - data["live_latency"]["latency_ms_p99"]
    )
    assert {t.key for t in LIVE_TARGETS} <= set(data["targets"]) | {
        "live_soak.rss_growth_pct",
        "live_soak.packets_lost",
        "live_soak.frames_dropped",
    }
    assert "with SAPIENT" in capsys.readouterr().out


@pytest.mark.slow
def test_quick_live_bench_of_a_vlp16_with_a_fixed_sensor(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["bench", "--live", "--quick", "--scenario", "walk-line", "--turret", "none"]
    assert run([*args, "--soak-s", "0", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "the LiDAR of walk-line" in out
    data = json.loads((tmp_path / "bench_live.json").read_text())
    assert data["settings"]["scenario"] == "walk-line"
    assert data["settings"]["turret"] == "none"
    lat = data["live_latency"]
    assert lat["scenario"] == "walk-line"
    assert lat["turret"] == "none"
    # 2 s of 0.1 s revolutions after the 0.5 s scan
    assert 15 <= lat["frames"] + lat["frames_dropped"] <= 21
    assert 0 < lat["latency_ms_p50"] <= lat["latency_ms_p99"]
    assert (lat["packets_lost"], lat["packets_malformed"]) == (0, 0)
    assert data["live_soak"] is None


@pytest.mark.slow
def test_quick_live_bench_over_ros2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--ros2``: emulate --ros2 and live with ros2:// LiDAR and turret, on a domain of
    the benchmark's own, over Cyclone on loopback."""
    from ros2_helpers import loopback_dds

    loopback_dds(tmp_path, monkeypatch)  # the loopback configuration, for the emulator too
    args = ["bench", "--live", "--quick", "--ros2", "--soak-s", "0"]
    assert run([*args, "--out", str(tmp_path / "out")]) == 0
    assert "over ROS 2 (DDS)" in capsys.readouterr().out
    data = json.loads((tmp_path / "out" / "bench_live.json").read_text())
    assert (data["settings"]["chain"], data["settings"]["turret"]) == ("ros2", "ros2")
    lat = data["live_latency"]
    assert lat["turret"] == "ros2:///turret"
    # 2 s of flight at 10 Hz after the scan: every frame logged or dropped
    assert 15 <= lat["frames"] + lat["frames_dropped"] <= 21
    assert 0 < lat["latency_ms_p50"] <= lat["latency_ms_p99"]
    assert data["live_soak"] is None


def test_growth_counts_from_the_end_of_the_warm_up() -> None:
    samples = [(0.0, 50.0), (5.0, 120.0), (10.0, 100.0), (15.0, 103.0), (20.0, 101.0)]
    # from the first sample at or after 10 s (100 MB) to the largest after it (103 MB)
    assert rss_growth_pct(samples, 10.0) == pytest.approx(3.0)
    assert rss_growth_pct(samples, 7.5) == pytest.approx(3.0)
    assert rss_growth_pct(samples, 16.0) == 0.0
    with pytest.raises(ConfigError, match="warm-up"):
        rss_growth_pct(samples, 25.0)


def test_resident_memory_counts_touched_pages() -> None:
    # a fresh anonymous mapping, not the heap: after a long test session the allocator
    # may hand back 64 MB that an earlier test freed and that is still resident
    with mmap.mmap(-1, 64_000_000) as mapping:
        before = resident_mb()
        block = np.frombuffer(mapping, dtype=np.uint8)
        block[::4096] = 1  # every page written
        after = resident_mb()
        del block
    assert after - before > 50.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--soak-s", "30"], "go with --live"),
        (["--live", "--rounds", "2"], "not --live"),
        (["--live", "--soak-s", "30", "--warmup-s", "40"], "shorter than the soak"),
        (["--live", "--latency-s", "0"], "flight of > 0 s"),
        (["--live", "--soak-s", "-1"], "0: none"),
        (["--scenario", "walk-line"], "go with --live"),
        (["--turret", "none"], "go with --live"),
        (["--live", "--scenario", "nowhere"], "unknown scenario 'nowhere'"),
    ],
)
def test_bad_live_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert run(["bench", "--out", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert "\n" not in err
    assert not (tmp_path / "bench_live.json").exists()


def test_live_settings_are_checked() -> None:
    assert LiveSettings().checked() == LiveSettings(20.0, 600.0, 60.0, 5.0, None)
    assert LiveSettings(soak_s=0.0, warmup_s=60.0).checked().soak_s == 0.0  # no soak
    with pytest.raises(ConfigError, match="sampling"):
        LiveSettings(sample_s=0.0).checked()


def test_a_live_request_gives_the_options_over_the_chosen_settings() -> None:
    """What is not given is the quick (or full) run's; --turret none drives no turret,
    --ros2 the ROS 2 chain."""
    quick = live_request(True, soak_s=0.0, turret="none")
    assert quick.settings == LiveSettings(
        LIVE_QUICK.latency_s, 0.0, LIVE_QUICK.warmup_s, LIVE_QUICK.sample_s, LIVE_QUICK.scan_s
    )
    assert (quick.turret, quick.chain) == (False, "livox")
    ptu = live_request(False, turret="ptu", ptu_baud=38400, scenario="walk-line")
    assert (ptu.settings.turret, ptu.settings.ptu_baud, ptu.settings.scenario) == (
        "ptu",
        38400,
        "walk-line",
    )
    assert ptu.turret
    ros2 = live_request(False, ros2=True)
    assert (ros2.chain, ros2.settings.turret) == ("ros2", LiveSettings().turret)
    with pytest.raises(ConfigError, match="ROS 2 turret"):
        live_request(False, ros2=True, turret="ptu")
