"""The track layer's settings (``track.multi``): its filters' noises, its gates, and
the lives of its tracks."""

from __future__ import annotations

from dataclasses import dataclass

from scipy.stats import chi2

from dronetrack.errors import ConfigError

__all__ = ["TrackSettings"]


@dataclass(frozen=True, slots=True)
class TrackSettings:
    """The track layer's parameters (SI units; see ``track.multi``'s docstring).

    sigma_acc: σ_a; sigma_meas: σ₀; gate_probability: the χ²₃ quantile of the
    Mahalanobis gate; v_max, gate_m: the speed gate (as the detect stage's);
    coast_s: the longest a track lives missed (in view without an update);
    unseen_s: the longest it lives without an update, in view or not (None: coast_s);
    probation_s: the longest a track no cluster has updated since its birth lives
    missed (``track.probation``; None: coast_s);
    stale_s: after this long
    without one, only a confirmed candidate's cluster updates it; birth_sigma_v: the
    velocity's σ at birth; max_tracks: the most tracks kept (those the classes hold no
    drone die first, then the longest unseen; of equals, the least updated); merge_m,
    merge_s: two tracks this close for this long follow one object; share_m: so do two
    this close for merge_s that take one cluster in turn.
    """

    sigma_acc: float = 5.0
    sigma_meas: float = 0.2
    gate_probability: float = 0.9999
    v_max: float = 15.0
    gate_m: float = 1.0
    coast_s: float = 5.0
    unseen_s: float | None = None
    probation_s: float | None = None
    stale_s: float = 0.3
    stale_gate_m: float = 5.0
    birth_sigma_v: float = 5.0
    max_tracks: int = 64
    merge_m: float = 1.0
    merge_s: float = 1.0
    share_m: float = 3.0

    def __post_init__(self) -> None:
        for name in ("sigma_acc", "sigma_meas", "v_max", "coast_s", "stale_s", "birth_sigma_v"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"tracks: {name} must be positive, got {getattr(self, name)}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ConfigError(
                f"tracks: gate_probability must be in (0, 1), got {self.gate_probability}"
            )
        if self.merge_m < 0 or self.merge_s < 0:
            raise ConfigError(
                f"tracks: need merge_m ≥ 0 and merge_s ≥ 0, got {self.merge_m}, {self.merge_s}"
            )
        if self.unseen_s is not None and not self.unseen_s >= self.coast_s:
            raise ConfigError(
                f"tracks: need unseen_s ≥ coast_s, got {self.unseen_s}, {self.coast_s}"
            )
        if self.probation_s is not None and not self.probation_s > 0:
            raise ConfigError(f"tracks: probation_s must be positive, got {self.probation_s}")
        if self.gate_m < 0 or self.max_tracks < 1:
            raise ConfigError(
                f"tracks: need gate_m ≥ 0 and max_tracks ≥ 1, got {self.gate_m}, {self.max_tracks}"
            )

    @property
    def gate(self) -> float:
        """γ: the Mahalanobis gate, χ²₃ at ``gate_probability``."""
        return float(chi2.ppf(self.gate_probability, 3))
