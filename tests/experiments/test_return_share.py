"""The drone's share of frames with a return by range, measured on the simulator
(``experiments.return_share``), and the figures the classes use
(``config.reach.RETURN_SHARE``)."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.classify.return_share import return_share
from dronetrack.config.reach import RETURN_SHARE
from dronetrack.errors import InputError
from dronetrack.experiments.return_share import fit_return_share, main, measure


def test_the_fit_gives_back_a_logistics_r50_and_width() -> None:
    ranges = np.arange(100.0, 201.0, 10.0)
    rng = np.random.default_rng(2)
    frames = np.full(len(ranges), 4000)
    shares = rng.binomial(frames, return_share(ranges, 150.0, 6.0)) / frames
    r50, s = fit_return_share(ranges, shares, frames)
    assert r50 == pytest.approx(150.0, abs=0.5)
    assert s == pytest.approx(6.0, rel=0.05)


def test_shares_that_never_cross_a_half_are_refused() -> None:
    with pytest.raises(InputError, match="span 1/2"):
        fit_return_share([100.0, 110.0, 120.0], [0.99, 0.95, 0.9], [400, 400, 400])


def test_bad_arguments_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--ranges", "100,far"])
    assert stop.value.code == 2
    assert "comma-separated" in capsys.readouterr().err


@pytest.mark.slow
def test_the_classes_share_is_the_simulators() -> None:
    """Five ranges about r₅₀ flown on a seed the figures were not measured on (400
    frames each): the fit lands within its sampling error of the figures the classes
    use (r₅₀ to 2 m, s to 20 %; the binomial σ of 400 frames is 0.025, about 0.5 m of
    r₅₀ and 6 % of s)."""
    r50, s = RETURN_SHARE[("avia", "phantom4")]
    ranges = [125.0, 135.0, 140.0, 145.0, 155.0]
    shares, frames, distances = measure(ranges, [12], sensor="avia", drone="phantom4")
    assert np.all(np.asarray(distances) > ranges)  # the drone is above the sensor
    fit_r50, fit_s = fit_return_share(distances, shares, frames)
    assert fit_r50 == pytest.approx(r50, abs=2.0)
    assert fit_s == pytest.approx(s, rel=0.2)
