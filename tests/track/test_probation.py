"""The probation of a track born on scant evidence (``track.probation``): the predictive
probability of a run of misses, and the least run that is unlikely enough."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate
from scipy.stats import beta

from dronetrack.errors import ConfigError
from dronetrack.track.probation import miss_run_probability, probation_frames


@pytest.mark.parametrize("k", [0, 1, 3, 15, 40])
def test_two_of_four_gives_the_closed_form(k: int) -> None:
    """Beta(3, 3) posterior: P(K) = 60 / ((K+5)(K+4)(K+3))."""
    assert miss_run_probability(2, 4, k) == pytest.approx(60.0 / ((k + 5) * (k + 4) * (k + 3)))


@pytest.mark.parametrize(("hits", "frames", "k"), [(1, 1, 2), (2, 4, 7), (3, 5, 4), (5, 9, 10)])
def test_the_probability_is_the_posterior_mean_of_a_run_of_misses(
    hits: int, frames: int, k: int
) -> None:
    """P(K) = ∫ (1 − q)^K Beta(q; M + 1, N − M + 1) dq, by quadrature."""
    posterior = beta(hits + 1, frames - hits + 1)
    value, _ = integrate.quad(lambda q: (1.0 - q) ** k * posterior.pdf(q), 0.0, 1.0)
    assert miss_run_probability(hits, frames, k) == pytest.approx(value, rel=1e-9)


@pytest.mark.parametrize(
    ("hits", "frames", "alpha", "k"),
    [
        (2, 4, 0.01, 15),  # 60/(20·19·18) = 0.0088 ≤ 0.01 < 60/(19·18·17) = 0.0103
        (1, 1, 0.1, 3),  # 2/((K+2)(K+1)): 2/20 = 0.1 at K = 3, 2/12 at K = 2
        (1, 1, 0.5, 1),  # 2/6 at K = 1
        (3, 3, 0.01, 5),  # 24/((K+4)(K+3)(K+2)(K+1)): 24/3024 at 5, 24/1680 at 4
    ],
)
def test_known_probations(hits: int, frames: int, alpha: float, k: int) -> None:
    assert probation_frames(hits, frames, alpha) == k


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(0, 12), st.floats(1e-9, 0.999))
def test_the_probation_is_the_least_run_unlikely_enough(
    hits: int, extra: int, alpha: float
) -> None:
    frames = hits + extra
    k = probation_frames(hits, frames, alpha)
    assert k >= 1
    assert miss_run_probability(hits, frames, k) <= alpha * (1 + 1e-12)
    if k > 1:
        assert miss_run_probability(hits, frames, k - 1) > alpha * (1 - 1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 8), st.integers(0, 8), st.floats(1e-6, 0.5), st.floats(0.01, 0.99))
def test_the_probation_grows_with_less_evidence_and_a_smaller_alpha(
    hits: int, extra: int, alpha: float, shrink: float
) -> None:
    frames = hits + extra
    k = probation_frames(hits, frames, alpha)
    assert probation_frames(hits, frames, alpha * shrink) >= k
    assert probation_frames(hits, frames + 1, alpha) >= k  # one frame more without a return
    assert probation_frames(hits + 1, frames + 1, alpha) <= k  # one return more


def test_the_probation_grows_as_alpha_to_minus_one_over_m_plus_one() -> None:
    """P(K) ~ Γ(N + 2)/Γ(N − M + 1) K^−(M+1): K ≈ (C/α)^(1/(M+1)) for small α."""
    c = math.gamma(6) / math.gamma(3)  # M = 2, N = 4: 60
    for alpha in (1e-6, 1e-9):
        assert probation_frames(2, 4, alpha) == pytest.approx((c / alpha) ** (1 / 3), rel=0.01)


@pytest.mark.parametrize(
    ("hits", "frames", "alpha", "match"),
    [(0, 4, 0.01, "hits"), (5, 4, 0.01, "hits"), (2, 4, 0.0, "alpha"), (2, 4, 1.0, "alpha")],
)
def test_bad_arguments_are_refused(hits: int, frames: int, alpha: float, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        probation_frames(hits, frames, alpha)
    with pytest.raises(ConfigError, match="misses"):
        miss_run_probability(2, 4, -1)
