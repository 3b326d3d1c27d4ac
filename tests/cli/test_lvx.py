"""``record --format lvx`` then ``info`` and ``track``: the round trip against the same
flight recorded as a bag, and bad input as one ``error:`` line."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.sources.recordings.opener import open_recording
from lvx_files import mid40_lvx

SITE = Path(__file__).parents[2] / "examples" / "site.toml"


def _metrics(folder: Path) -> dict[str, float]:
    result: dict[str, float] = json.loads((folder / "metrics.json").read_text())
    return result


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 s of the default flight (after the 10 s background scan) from a fixed Avia, as
    an LVX file with its truth and scenario beside it, and the same run as a ROS 1 bag."""
    folder = tmp_path_factory.mktemp("lvx")
    lvx = folder / "flight.lvx"
    assert run(["record", "--out", str(lvx), "--seed", "2", "--duration", "20"]) == 0
    scenario = folder / "flight.scenario.toml"
    assert run(["record", "--config", str(scenario), "--out", str(folder / "flight.bag")]) == 0
    return lvx


@pytest.mark.slow
def test_the_lvx_holds_the_bags_points(flight: Path) -> None:
    """Frame by frame the same returns: positions within the packets' millimetre (√3 · 0.5
    mm), times within 2.5 firings of 4.167 µs (the grid's rounding and a shared firing)."""
    bag, lvx = open_recording(flight.with_suffix(".bag")), open_recording(flight)
    assert lvx.origin == bag.origin
    frames = 0
    for a, b in zip(bag.frames(), lvx.frames(), strict=True):
        frames += 1
        assert b.stamp == pytest.approx(a.stamp, abs=1e-9)
        assert len(b) == len(a)
        ia, ib = np.lexsort((a.points[:, 0], a.t)), np.lexsort((b.points[:, 0], b.t))
        wa = a.points[ia] @ a.poses[0][:3, :3].T + a.poses[0][:3, 3]
        wb = b.points[ib] @ b.poses[0][:3, :3].T + b.poses[0][:3, 3]
        assert np.abs(wa - wb).max(initial=0.0) <= 0.87e-3 + 1e-5
        assert np.abs(a.t[ia] - b.t[ib]).max(initial=0.0) <= 2.5 * 4167e-9
    assert frames == 300


@pytest.mark.slow
def test_track_of_the_lvx_gives_the_bags_metrics(
    flight: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``track`` of the LVX file with its scenario and truth against ``track`` of the bag.

    Measured on seeds 0-5 (20 s each): frames, first lock, maximum tracking distance and
    the target's points the same (distance within 1e-8 m, points within 1 of 1,300),
    coverage within 1 point, RMSE within 6 %.  The inputs differ only by the packets'
    millimetres and firing grid (the test above), but the particle filter, fed returns
    a fraction of a millimetre apart, draws other particles from then on; ``rmse_m``
    runs over the frames after a loss too, where the two estimates drift apart, so it
    moves most.  The bounds leave room over the largest differences measured.
    """
    folder = flight.parent
    capsys.readouterr()
    assert run(["info", str(flight)]) == 0
    listing = capsys.readouterr().out
    assert "3GGDJ1234567890" in listing
    assert "Avia packets, extrinsics on" in listing
    assert "(lvx, 30.000 s from" in listing  # the title may wrap before the start time
    assert "2026-01-01T00:00:00.000+00:00" in listing
    assert run(["track", str(folder / "flight.bag"), "--out", str(folder / "tb")]) == 0
    args = ["--config", str(folder / "flight.scenario.toml")]
    args += ["--truth", str(folder / "flight.truth.csv"), "--out", str(folder / "tl")]
    assert run(["track", str(flight), *args]) == 0
    bag, lvx = _metrics(folder / "tb"), _metrics(folder / "tl")
    assert lvx["frames"] == bag["frames"] == 200
    assert lvx["first_lock_s"] == pytest.approx(bag["first_lock_s"], abs=1e-6)
    assert abs(lvx["coverage_pct"] - bag["coverage_pct"]) <= 2.0
    for key, rel in (
        ("max_tracking_distance_m", 1e-3),
        ("target_points_total", 0.01),
        ("rmse_m", 0.10),
    ):
        assert abs(lvx[key] - bag[key]) <= rel * bag[key], (key, bag[key], lvx[key])
    assert lvx["skipped_messages"] == {}
    assert "warnings" not in lvx  # the extrinsics gave the sensor's pose


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["record", "--out", "{tmp}/x.lvx", "--turret", "tracking"], "not --turret tracking"),
        (["record", "--out", "{tmp}/x.lvx", "--compress"], "--compress applies to bags"),
        (["record", "--out", "{tmp}/x.lvx2"], "(--sensor mid360), not 'avia'"),
        (["record", "--out", "{tmp}/x.lvx", "--format", "lvx2"], "name it x.lvx2, or give"),
        (["record", "seed002-relative", "--out", "{tmp}/x.lvx2"], "moving observer"),
        (["track", "{tmp}/cut.lvx"], "truncated: frame"),
        (["info", "{tmp}/cut.lvx"], "truncated: frame"),
        (["track", "{tmp}/magic.lvx"], "magic code 0x00000000 is not 0xAC0EA767"),
        (["track", "{tmp}/bag.lvx", "--truth", "{tmp}/none.csv"], "truth CSV not found"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    flight: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    data = flight.read_bytes()[:2_000_000]
    (tmp_path / "cut.lvx").write_bytes(data[:1_000_003])
    (tmp_path / "magic.lvx").write_bytes(data[:20] + bytes(4) + data[24:])
    (tmp_path / "bag.lvx").write_bytes(
        flight.with_suffix(".bag").read_bytes()
    )  # a bag all the same
    capsys.readouterr()
    assert run([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert len(err.splitlines()) == 1


def test_track_of_a_mid40_recording_with_an_avia_site_file_records_the_mid40(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The LVX header's device type (1, a Mid-40) overrides examples/site.toml's Avia,
    with one warning line naming both, and config.toml records what was replayed."""
    recording = mid40_lvx(tmp_path / "mid40.lvx", packets=300)  # 0.3 s
    out = tmp_path / "run"
    args = ["--config", str(SITE), "--background-from", "0", "--period", "0.01"]
    assert run(["track", str(recording), *args, "--out", str(out)]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning:" in line]
    assert len(warnings) == 1
    assert "Livox Mid-40" in warnings[0]
    assert "'avia'" in warnings[0]
    config = tomllib.loads((out / "config.toml").read_text())
    assert config["sensor"]["model"] == "mid40"
    assert _metrics(out)["frames"] == 30
