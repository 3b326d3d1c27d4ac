"""How long a track born on scant evidence may go missed before it ends: its probation.

The detect stage confirms a candidate after M returns in its last N frames
(``detect.tentative``).  A sensor's own false returns now and then pass that test by
chance, and the track born on them is never updated again; it would otherwise live
``coast_s`` (5 s) in view as an object no class has told yet, which a site's C2 hears
as a possible drone.  A real object returns again.

Let q be the object's probability of a return in a frame.  With a uniform prior, the
confirmation's M of N gives the posterior

    q | M of N  ~  Beta(M + 1, N − M + 1),

and the predictive probability that it then gives no return in K frames in a row is

    P(K) = E[(1 − q)^K] = B(M + 1, N − M + 1 + K) / B(M + 1, N − M + 1).

The probation is the least K with P(K) ≤ α: a real object so confirmed goes that long
unseen with probability at most α.  For M = 2, N = 4, P(K) = 60 / ((K+5)(K+4)(K+3)),
and α = 0.01 gives K = 15 frames, 1.5 s at 10 Hz.  P(K) falls as K^−(M+1), so the
probation grows slowly as α shrinks (α^−1/(M+1)).
"""

from __future__ import annotations

import math

from scipy.special import betaln

from dronetrack.errors import ConfigError

__all__ = ["miss_run_probability", "probation_frames"]

_MAX_DOUBLINGS = 1100  # 2^1100 frames exceeds any α > 0 a float can hold


def miss_run_probability(hits: int, frames: int, misses: int) -> float:
    """P(K): the predictive probability of ``misses`` frames in a row without a return
    for an object confirmed on ``hits`` returns in ``frames`` frames (uniform prior)."""
    _check(hits, frames)
    if misses < 0:
        raise ConfigError(f"probation: misses must be ≥ 0, got {misses}")
    return math.exp(_log_miss_run(hits, frames, misses))


def probation_frames(hits: int, frames: int, alpha: float) -> int:
    """The least K ≥ 1 with P(K) ≤ ``alpha`` (see the module docstring): how many frames
    in a row a track born on ``hits`` of ``frames`` may be missed before it ends."""
    _check(hits, frames)
    if not 0.0 < alpha < 1.0:
        raise ConfigError(f"probation: alpha must be in (0, 1), got {alpha}")
    log_alpha = math.log(alpha)

    def above(k: int) -> bool:  # ln P(K) > ln α
        return _log_miss_run(hits, frames, k) > log_alpha

    hi = 1
    for _ in range(_MAX_DOUBLINGS):
        if not above(hi):
            break
        hi *= 2
    else:  # pragma: no cover - P(K) → 0 as K → ∞ for every M ≥ 1
        raise ConfigError(f"probation: no K with P(K) ≤ {alpha}")
    lo = hi // 2  # P(lo) > α (or lo = 0), P(hi) ≤ α
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if above(mid):
            lo = mid
        else:
            hi = mid
    return hi


def _log_miss_run(hits: int, frames: int, misses: int) -> float:
    """ln P(K) = ln B(M + 1, N − M + 1 + K) − ln B(M + 1, N − M + 1)."""
    a, b = hits + 1, frames - hits + 1
    return float(betaln(a, b + misses) - betaln(a, b))


def _check(hits: int, frames: int) -> None:
    if not 1 <= hits <= frames:
        raise ConfigError(f"probation: need 1 ≤ hits ≤ frames, got {hits}, {frames}")
