"""How often the drone the site guards returns a point at a range, and the test of a
track that returned more often than it could.

A drone hovering on the sensor's axis, where the scan pattern is densest, returns at
least one point in a share P(r) of the frames at range r, which falls from nearly 1 to
0 over a few tens of metres as its returns grow too weak to detect (``sensor_physics``):

    P(r) = 1 / (1 + exp((r − r₅₀) / s))

with r₅₀ the range of one frame in two and s the fall's width [m], both measured for
a sensor and drone pair (``experiments.return_share``; ``config.reach.RETURN_SHARE``).
Off the axis the pattern is sparser, so P(r) bounds the share anywhere in the field.

A track seen in k of the n frames it was in view after its birth, at ranges r_i, has
under the drone hypothesis k ~ Σ Bernoulli(p_i), p_i ≤ P(r_i), mean μ ≤ Σ P(r_i).  The
Chernoff bound on the upper tail of such a sum, for k > μ,

    P(K ≥ k) ≤ e^{−μ} (e μ / k)^k   ⟺   ln P(K ≥ k) ≤ k − μ − k ln(k / μ)

says how unlikely a drone is to have returned that often.  Below ``ALPHA`` the track
is larger or brighter than the drone: a structure's part, a vehicle, a large bird.
The birth's frames are left out: a track is born because it returned points
(``detect.tentative``'s M of N), which says nothing of how often it returns.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray

__all__ = ["ALPHA", "more_often_than_drone", "return_share"]

# the least tail probability of a drone's count: one drone track in a thousand is held
# to return too often by chance
ALPHA = 1e-3


def return_share(range_m: FloatArray, r50_m: float, scale_m: float) -> FloatArray:
    """P(r) (see the module docstring) at each range ``range_m`` [m]."""
    # P(r) = 1 / (1 + exp((r − r₅₀) / s)), written through tanh so no exp overflows
    out: FloatArray = 0.5 * (1.0 - np.tanh(0.5 * (np.asarray(range_m) - r50_m) / scale_m))
    return out


def more_often_than_drone(
    hits: NDArray[np.int64], expected: FloatArray, alpha: float = ALPHA
) -> NDArray[np.bool_]:
    """Whether each count of frames with returns ``hits`` (k) is too many for the drone
    whose expected count over the same frames is ``expected`` (μ = Σ P(r_i)):
    k > μ and k − μ − k ln(k / μ) < ln α (μ = 0: any k ≥ 1)."""
    k = np.asarray(hits, dtype=np.float64)
    mu = np.asarray(expected, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_tail = np.where(mu > 0, k - mu - k * np.log(k / mu), -np.inf)
    out: NDArray[np.bool_] = (k > mu) & (log_tail < np.log(alpha))
    return out
