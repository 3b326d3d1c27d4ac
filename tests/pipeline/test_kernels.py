"""The numba kernels are compiled before the timed loop, never inside it.

``test_nothing_compiles_inside_a_run`` runs in a fresh interpreter, so no kernel
signature compiled by another test can hide one the warm-up misses: after each
run's warm-up, the set of compiled signatures must not grow until the run ends.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from dronetrack.pipeline.kernels import PIPELINE_WARM_UPS, compiled_signatures, dispatchers, warm_up

CHECK = textwrap.dedent(
    """
    import json, sys
    from pathlib import Path
    from dronetrack.pipeline import kernels
    from dronetrack.sources.recordings.opener import open_recording
    from dronetrack.jobs.replay import recording_config, run_replay
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    out = Path(sys.argv[1])
    grown = {}
    warmed = {}

    def snapshot(done, total, compiled):
        if done == total:
            warmed.clear()
            warmed.update(kernels.compiled_signatures())

    def check(what):
        after = kernels.compiled_signatures()
        new = {k: v for k, v in after.items() if v != warmed.get(k, 0)}
        if new:
            grown[what] = new

    def short(cfg, **tracker):
        pipeline = cfg.pipeline
        bg = pipeline.background.model_copy(update={"scan_s": 1.0})
        t = pipeline.tracker.model_copy(update=tracker)
        pipeline = pipeline.model_copy(update={"background": bg, "tracker": t})
        return cfg.model_copy(update={"duration_s": 1.5, "pipeline": pipeline})

    cases = [
        ("default", {}),
        ("default", {"kind": "pf-ca"}),
        ("default", {"kind": "pf-systematic"}),
        ("default", {"kind": "aekf-ca"}),
        ("default", {"kind": "ekf-dogru"}),
        ("indoor-horizontal", {"kind": "pf-cv"}),
        ("mid360-aggressive", {}),
        ("seed002-relative", {}),
        ("seed003-field", {}),
        ("walk-line", {}),
    ]
    for name, tracker in cases:
        run_simulation(short(get_scenario(name), **tracker), compiling=snapshot)
        check(f"simulate {name} {tracker}")
    for path in sorted(out.iterdir()):
        rec = open_recording(path)
        run_replay(rec, recording_config(rec, None), compiling=snapshot)
        check(f"track {path.name}")
    print(json.dumps(grown))
    """
)


@pytest.mark.slow
def test_nothing_compiles_inside_a_run(tmp_path: Path) -> None:
    from dronetrack.cli.main import run

    recordings = tmp_path / "recordings"
    recordings.mkdir()
    for fmt, points, name in (
        ("ros1", "--livox-custom", "custom.bag"),
        ("ros2-mcap", "--pointcloud2", "cloud.mcap"),
    ):
        args = ["record", "--format", fmt, points, "--duration", "1"]
        assert run([*args, "--out", str(recordings / name)]) == 0
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run(
        [sys.executable, "-c", CHECK, str(recordings)],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    grown = json.loads(done.stdout.strip().splitlines()[-1])
    assert grown == {}, f"kernels compiled inside the timed loop: {grown}"


def test_warm_up_reports_what_it_compiled() -> None:
    """A second warm-up in the same process finds every kernel compiled: nothing to
    report; the package's kernels are all found."""
    warm_up(PIPELINE_WARM_UPS)
    report = warm_up(PIPELINE_WARM_UPS)
    assert report.compiled == 0
    assert report.seconds >= 0
    names = {f"{d.py_func.__module__}.{d.__name__}" for d in dispatchers()}
    assert "dronetrack.track.particle._predict_kernel" in names
    assert "dronetrack.geometry.transforms._transform_kernel" in names
    assert all(n > 0 for k, n in compiled_signatures().items() if "track.particle" in k)


def test_warm_up_leaves_a_seeded_world_as_it_was() -> None:
    """Two worlds of one seed, one warmed up: their frames are identical."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.sim.build import build_world

    cfg = get_scenario("seed002-relative")  # an observer: its poses, and its drift stream
    cfg = cfg.model_copy(
        update={"observer": cfg.observer.model_copy(update={"odometry_sigma_m": 0.1})}  # type: ignore[union-attr]
    )
    plain = build_world(cfg, np.random.default_rng(5))
    warmed = build_world(cfg, np.random.default_rng(5))
    warmed.warm_up()
    for _ in range(3):
        a, _ = plain.step()
        b, _ = warmed.step()
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.poses, b.poses)
