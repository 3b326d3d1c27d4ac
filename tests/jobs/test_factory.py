"""Configuration to components: each tracker kind gets its model and noise."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.config.pipeline import PipelineConfig, TrackerConfig
from dronetrack.jobs.factory import (
    CA_SIGMA_ACC,
    DEFAULT_S_DIAG,
    build_pipeline,
    build_tracker,
    noise_parameters,
    resolve_tracker,
)
from dronetrack.sim.turret import make_turret
from dronetrack.track.particle import ParticleTracker

TURRET = make_turret("widowx")


def _tracker(cfg: TrackerConfig) -> ParticleTracker:
    pipe = build_pipeline(
        PipelineConfig(tracker=cfg),
        0.1,
        TURRET.mount,
        (TURRET.pan.lower, TURRET.pan.upper),
        (TURRET.tilt.lower, TURRET.tilt.upper),
        np.random.default_rng(0),
    )
    assert isinstance(pipe.tracker, ParticleTracker)
    return pipe.tracker


@pytest.mark.parametrize(
    ("kind", "model", "sigma_acc"),
    [("pf-delta", "delta", 0.0), ("pf-cv", "cv", 0.0), ("pf-ca", "ca", CA_SIGMA_ACC)],
)
def test_each_kind_gets_its_motion_model(kind: str, model: str, sigma_acc: float) -> None:
    pf = _tracker(TrackerConfig(kind=kind, particles=100)).filter  # type: ignore[arg-type]
    assert pf.model == model
    assert pf.noise.sigma_acc == sigma_acc
    # Eq. (11) at 15 m/s, 15 m/s², 10 Hz: σ_pos = σ_vel = 0.5, σ_m = s_diag / 2.
    assert pf.noise.sigma_pos == pytest.approx(0.5)
    assert pf.noise.sigma_vel == pytest.approx(0.5)
    assert pf.noise.sigma_m == pytest.approx(DEFAULT_S_DIAG / 2)


def test_given_sigmas_override_eq11() -> None:
    cfg = TrackerConfig(kind="pf-ca", sigma_acc=0.7, sigma_m=0.05, v_max=3.0)
    n = noise_parameters(cfg, 0.1)
    assert (n.sigma_acc, n.sigma_m) == (0.7, 0.05)
    assert n.sigma_pos == pytest.approx(0.1)  # v_max T / 3


def test_s_diag_comes_from_the_config_then_the_drone() -> None:
    drone = resolve_tracker(TrackerConfig(), 0.1, s_diag=0.12)
    assert drone.s_diag == 0.12
    assert drone.sigma_m == pytest.approx(0.06)
    given = resolve_tracker(TrackerConfig(s_diag=0.3), 0.1, s_diag=0.12)
    assert given.sigma_m == pytest.approx(0.15)
    assert resolve_tracker(TrackerConfig(), 0.1).s_diag == DEFAULT_S_DIAG
    # Resolved values are written out, and resolving again changes nothing.
    assert resolve_tracker(drone, 0.1, s_diag=0.5) == drone


def test_pf_systematic_runs_seed002s_filter_through_the_command_line_path() -> None:
    """Built the way the CLI builds it (overrides re-validate every field), pf-systematic
    is 2,000 particles with systematic resampling, and the resolved config says so."""
    from dronetrack.config.run import apply_overrides
    from dronetrack.jobs.simulate import resolve_run
    from dronetrack.sim.scenarios import SCENARIOS

    cfg = resolve_run(apply_overrides(SCENARIOS["seed002-relative"], tracker="pf-systematic"))
    tc = cfg.pipeline.tracker
    assert (tc.particles, tc.resampling) == (2000, "systematic")
    tracker = build_tracker(tc, 0.1, np.random.default_rng(0))
    assert isinstance(tracker, ParticleTracker)
    assert tracker.filter.X.shape[0] == 2000
    given = apply_overrides(SCENARIOS["default"], tracker="pf-systematic", particles=300)
    assert resolve_run(given).pipeline.tracker.particles == 300
    assert resolve_run(SCENARIOS["default"]).pipeline.tracker.particles == 5000
