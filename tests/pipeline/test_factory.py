"""Configuration to components: each tracker kind gets its model and noise."""

from __future__ import annotations

from dataclasses import replace
from typing import get_args

import numpy as np
import pytest

from dronetrack.config.pipeline import (
    AcquisitionConfig,
    BackgroundConfig,
    ControllerConfig,
    ControllerMode,
    DetectorConfig,
    KalmanConfig,
    PipelineConfig,
    TrackerConfig,
    TrackerKind,
    TracksConfig,
)
from dronetrack.config.rig import make_turret
from dronetrack.control.controller import TurretController
from dronetrack.control.strategies import MODES as STRATEGIES
from dronetrack.control.strategies import ScanStrategyController
from dronetrack.detect.candidates import SEED002_DETECTOR, SEED003_DETECTOR
from dronetrack.errors import ConfigError
from dronetrack.pipeline import Pipeline
from dronetrack.pipeline.factory import CONTROLLERS, build_pipeline, probation_s
from dronetrack.pipeline.trackers import (
    CA_SIGMA_ACC,
    DEFAULT_S_DIAG,
    TRACKER_NAMES,
    TRACKERS,
    build_tracker,
    check_registry,
    noise_parameters,
    resolve_tracker,
)
from dronetrack.track.cluster_kalman import AdaptiveEKF, CentroidEKF, ConstantAccelerationKF
from dronetrack.track.multi import MultiTargetTracker
from dronetrack.track.particle import ParticleTracker
from dronetrack.track.resample import RESAMPLERS
from dronetrack.track.sphere_kalman import CatalanoEKF, DogruEKF

TURRET = make_turret("widowx")


def _pipeline(cfg: PipelineConfig) -> Pipeline:
    return build_pipeline(
        cfg,
        0.1,
        TURRET.mount,
        (TURRET.pan.lower, TURRET.pan.upper),
        (TURRET.tilt.lower, TURRET.tilt.upper),
        np.random.default_rng(0),
    )


def _tracker(cfg: TrackerConfig) -> ParticleTracker:
    pipe = _pipeline(PipelineConfig(tracker=cfg))
    assert isinstance(pipe.tracker, ParticleTracker)
    return pipe.tracker


def test_the_background_settings_reach_the_scanned_model() -> None:
    bg = BackgroundConfig(resolution_m=0.5, inflate_voxels=2, lookup_depth=1, min_hits=3)
    for need in (0, 2):
        model = _pipeline(
            PipelineConfig(background=bg.model_copy(update={"min_neighbours": need}))
        ).background
        assert model is not None
        assert not model.ready
        kept = (model.resolution, model.inflate, model.lookup_depth, model.min_hits)
        assert (*kept, model.min_neighbours) == (0.5, 2, 1, 3, need)


def test_near_track_gives_the_scanning_pipeline_a_range_image() -> None:
    assert _pipeline(PipelineConfig()).ranges is None
    scanning = _pipeline(PipelineConfig(background=BackgroundConfig(near_track=True)))
    assert scanning.ranges is not None
    assert not scanning.ranges.ready
    np.testing.assert_allclose(scanning.ranges.origin, TURRET.mount.base)


def test_a_track_never_updated_after_its_birth_is_on_probation_for_k_frames() -> None:
    """2 of 4 and α = 0.01 give K = 15 frames (``track.probation``): 1.5 s at 10 Hz,
    0.75 s at 20 Hz; 3 of 3 gives K = 5; at α = 0 the probation is coast_s."""
    for period, expected in ((0.1, 1.5), (0.05, 0.75)):
        cfg = PipelineConfig(acquisition=AcquisitionConfig(enabled=True))
        acquisition = build_pipeline(
            cfg,
            period,
            TURRET.mount,
            (TURRET.pan.lower, TURRET.pan.upper),
            (TURRET.tilt.lower, TURRET.tilt.upper),
            np.random.default_rng(0),
        ).acquisition
        assert acquisition is not None
        assert isinstance(acquisition.objects, MultiTargetTracker)
        assert acquisition.objects.settings.probation_s == pytest.approx(expected)
    strict = AcquisitionConfig(enabled=True, confirm_hits=3, confirm_frames=3)
    assert probation_s(strict, TracksConfig(), 0.1) == pytest.approx(0.5)
    assert probation_s(strict, TracksConfig(probation_alpha=0.0), 0.1) is None
    assert probation_s(strict, TracksConfig(), None) is None


def test_the_registries_hold_each_configurable_name_once() -> None:
    assert tuple(TRACKERS) == get_args(TrackerKind) == TRACKER_NAMES
    assert tuple(CONTROLLERS) == get_args(ControllerMode)
    # The import-time check refuses a registry with a name missing, extra or repeated.
    for keys in (TRACKER_NAMES[:-1], (*TRACKER_NAMES, "pf-new"), TRACKER_NAMES[::-1]):
        with pytest.raises(ConfigError, match="tracker registry"):
            check_registry("tracker", keys, TRACKER_NAMES)


EXPECTED_TRACKERS = {
    "pf-delta": ParticleTracker,
    "pf-cv": ParticleTracker,
    "pf-ca": ParticleTracker,
    "pf-systematic": ParticleTracker,
    "ekf-dogru": DogruEKF,
    "ekf-catalano": CatalanoEKF,
    "ekf-catalano-mod": CatalanoEKF,
    "ekf-cv": CentroidEKF,
    "kf-ca": ConstantAccelerationKF,
    "aekf-ca": AdaptiveEKF,
}


@pytest.mark.parametrize("kind", TRACKER_NAMES)
def test_each_kind_builds_its_tracker(kind: str) -> None:
    home = np.array([1.0, 2.0, 3.0])
    cfg = TrackerConfig(kind=kind, particles=100)  # type: ignore[arg-type]
    tracker = build_tracker(cfg, 0.1, np.random.default_rng(0), home=home)
    assert type(tracker) is EXPECTED_TRACKERS[kind]
    assert tracker.period == 0.1
    if isinstance(tracker, ParticleTracker):
        want = "systematic" if kind == "pf-systematic" else "multinomial"
        assert tracker.filter._resample is RESAMPLERS[want]
    else:
        np.testing.assert_array_equal(tracker.home, home)
    # Seed 000's search radii for Catalano et al.'s EKF: 0.2 m, and 1.5 m modified;
    # a configured radius replaces either.
    if isinstance(tracker, CatalanoEKF):
        assert tracker.fixed_radius == {"ekf-catalano": 0.2, "ekf-catalano-mod": 1.5}[kind]
        given = cfg.model_copy(update={"kalman": KalmanConfig(search_radius_m=0.7)})
        radius = build_tracker(given, 0.1, np.random.default_rng(0)).fixed_radius  # type: ignore[attr-defined]
        assert radius == 0.7
    # The detector behind a cluster tracker is its seed's preset; an ROI is centred on home.
    if isinstance(tracker, CentroidEKF | ConstantAccelerationKF):
        preset = SEED003_DETECTOR if kind == "ekf-cv" else SEED002_DETECTOR
        assert tracker.detector == preset
        roi = cfg.model_copy(update={"detector": DetectorConfig(roi_radius_m=30.0, eps_m=0.3)})
        built = build_tracker(roi, 0.1, np.random.default_rng(0), home=home)
        assert built.detector == replace(  # type: ignore[attr-defined]
            preset, roi_radius=30.0, roi_center_xy=(1.0, 2.0), eps=0.3
        )
    assert isinstance(tracker, AdaptiveEKF) == (kind == "aekf-ca")


@pytest.mark.parametrize("mode", get_args(ControllerMode))
def test_each_mode_builds_its_controller(mode: str) -> None:
    pipe = _pipeline(PipelineConfig(controller=ControllerConfig(mode=mode)))  # type: ignore[arg-type]
    kind = ScanStrategyController if mode in STRATEGIES else TurretController
    assert type(pipe.controller) is kind
    # ``truth``: the simulator's truth aimer steers while tracking, the controller stays out
    assert pipe.controller.mode == ("external" if mode == "truth" else mode)


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
    from dronetrack.config.scenarios import SCENARIOS
    from dronetrack.jobs.simulate import resolve_run

    cfg = resolve_run(apply_overrides(SCENARIOS["seed002-relative"], tracker="pf-systematic"))
    tc = cfg.pipeline.tracker
    assert (tc.particles, tc.resampling) == (2000, "systematic")
    tracker = build_tracker(tc, 0.1, np.random.default_rng(0))
    assert isinstance(tracker, ParticleTracker)
    assert tracker.filter.X.shape[0] == 2000
    given = apply_overrides(SCENARIOS["default"], tracker="pf-systematic", particles=300)
    assert resolve_run(given).pipeline.tracker.particles == 300
    assert resolve_run(SCENARIOS["default"]).pipeline.tracker.particles == 5000
