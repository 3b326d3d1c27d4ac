"""The field of regard as a site setting: validation, and what follows from it."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from dronetrack.config.pipeline import (
    DEFAULT_CROP_MAX_M,
    DEFAULT_CROP_MIN_M,
    CropConfig,
    FieldOfRegardConfig,
    PipelineConfig,
    crop_box,
    scan_area,
)
from dronetrack.jobs.run import outside_share

FIELD = FieldOfRegardConfig(pan_deg=(-90.0, 90.0), tilt_deg=(-40.0, 5.0), range_m=200.0)


def test_without_a_field_the_defaults_hold() -> None:
    cfg = PipelineConfig()
    assert crop_box(cfg, (0.0, 0.0, 1.0)) == (DEFAULT_CROP_MIN_M, DEFAULT_CROP_MAX_M)
    assert scan_area(cfg) == ((-60.0, 60.0), (-25.0, 5.0), 4.0)


def test_the_crop_box_and_the_scan_follow_the_field_unless_set() -> None:
    cfg = PipelineConfig(field_of_regard=FIELD)
    low, high = crop_box(cfg, (0.0, 0.0, 1.0))
    # x from the base to 200 m, y ±200 m (the pan ends), z from 1 m to 1 + 200 sin 40°.
    np.testing.assert_allclose(low, (0.0, -200.0, 1.0), atol=1e-9)
    np.testing.assert_allclose(high, (200.0, 200.0, 1.0 + 200.0 * np.sin(np.radians(40.0))))
    # The scan covers the field at 60°/s: 180° there and back in 6 s.
    assert scan_area(cfg) == ((-90.0, 90.0), (-40.0, 5.0), 6.0)
    full = PipelineConfig(field_of_regard=FieldOfRegardConfig(pan_deg=(-180.0, 180.0)))
    assert scan_area(full)[2] == pytest.approx(12.0)
    own = PipelineConfig(
        field_of_regard=FIELD, crop=CropConfig(min_m=(1.0, -5.0, 1.0), max_m=(50.0, 5.0, 9.0))
    )
    assert crop_box(own, (0.0, 0.0, 1.0)) == ((1.0, -5.0, 1.0), (50.0, 5.0, 9.0))


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"pan_deg": (10.0, -10.0)}, "pan_deg"),
        ({"pan_deg": (-200.0, 200.0)}, "pan_deg"),
        ({"tilt_deg": (-95.0, 0.0)}, "tilt_deg"),
        ({"range_m": 0.0}, "range_m"),
    ],
)
def test_bad_fields_are_refused(section: dict[str, object], message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        FieldOfRegardConfig.model_validate(section)
    with pytest.raises(ValidationError, match="together"):
        CropConfig(min_m=(0.0, 0.0, 0.0))


def test_outside_share_counts_from_the_first_frame_inside() -> None:
    inside = np.array([False, False, True, True, False, True, True, True])
    assert outside_share(inside) == pytest.approx(100.0 / 6)
    assert outside_share(np.zeros(4, dtype=bool)) == 100.0
    assert outside_share(np.zeros(0, dtype=bool)) == 0.0
