"""A sweep's combinations over their runs, and their ranking.

Each grid combination is summarised over its runs (seeds): mean and standard
deviation of coverage and of maximum tracking distance.  Its distance from the
analytic parameter set is the Euclidean distance of its
(σ_pos, σ_vel, σ_acc, σ_m) from eq. (11)'s for the same drone and frame period,
in their own units (m, m/s, m/s², m), as in the seed's figure; it is empty for
the Kalman filters, which have no such σ.

Combinations are ranked by coverage, then maximum tracking distance, each compared
at the precision the report prints it (``RESOLUTION``): combinations that read the
same there share a rank.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

from dronetrack.eval.plots import KALMAN_FILTERS
from dronetrack.experiments.sweep.runner import SIGMA_KEYS

__all__ = [
    "BEST",
    "COVERAGE",
    "DISTANCE",
    "EQ11_RESOLUTION",
    "RESOLUTION",
    "Combination",
    "eq11_distance",
    "rank_key",
    "rank_numbers",
    "ranked",
    "run_eq11_distance",
    "summarise",
]

COVERAGE, DISTANCE = "coverage_pct", "max_tracking_distance_m"
BEST = 10  # rows in the table of the best combinations
# The precision at which two combinations' means count as equal, as the report prints
# them.  Coverage: 0.1 percentage point, a fifth of one frame of a 20 s flight at
# 10 Hz.  Maximum tracking distance: 0.1 m, a fifteenth of the 1.5 m the default drone
# (15 m/s) flies between two frames, which is the step the metric really moves in;
# below it runs differ only by the turret's sub-millimetre pose (the range is taken
# from the sensor, which pan and tilt move).
RESOLUTION = {COVERAGE: 0.1, DISTANCE: 0.1}
# ‖σ − σ_eq11‖ to a thousandth (of a m, m/s, m/s²): a grid's σ steps are hundredths
# and more; what lies below is the float rounding of eq. (11)'s arithmetic.
EQ11_RESOLUTION = 1e-3


@dataclass(frozen=True, slots=True)
class Combination:
    """One grid point over its runs."""

    params: dict[str, Any]
    runs: int
    failed: int
    coverage_mean: float
    coverage_std: float
    distance_mean: float
    distance_std: float
    eq11_distance: float  # NaN without σ values

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in sorted(self.params.items())) or "(base)"


def _stats(values: list[float]) -> tuple[float, float]:
    a = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=np.float64)
    if len(a) == 0:
        return math.nan, math.nan
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else math.nan


def eq11_distance(sigma: dict[str, Any], eq11: dict[str, Any]) -> float:
    """‖σ − σ_eq11‖ over σ_pos, σ_vel, σ_acc, σ_m; NaN if a value is missing."""
    try:
        d = np.array([float(sigma[k]) - float(eq11[k]) for k in SIGMA_KEYS])
    except (KeyError, TypeError):
        return math.nan
    return float(np.sqrt(np.sum(d * d)))


def run_eq11_distance(row: dict[str, Any]) -> float:
    """A run's ‖σ − σ_eq11‖ to ``EQ11_RESOLUTION``; NaN for a Kalman filter, whose σ
    settings are not eq. (11)'s particle noise."""
    if row.get("tracker") in KALMAN_FILTERS:
        return math.nan
    d = eq11_distance(row.get("sigma") or {}, row.get("eq11") or {})
    return round(d / EQ11_RESOLUTION) * EQ11_RESOLUTION if math.isfinite(d) else d


def summarise(rows: list[dict[str, Any]]) -> list[Combination]:
    """The combinations of a sweep's result lines, in first-seen order."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        groups[json.dumps(row.get("params", {}), sort_keys=True)].append(row)
    out = []
    for params, group in groups.items():
        ok = [r for r in group if "error" not in r and isinstance(r.get("metrics"), dict)]
        cov = _stats([r["metrics"].get(COVERAGE) for r in ok])
        dist = _stats([r["metrics"].get(DISTANCE) for r in ok])
        d = [run_eq11_distance(r) for r in ok]
        out.append(
            Combination(
                params=json.loads(params),
                runs=len(ok),
                failed=len(group) - len(ok),
                coverage_mean=cov[0],
                coverage_std=cov[1],
                distance_mean=dist[0],
                distance_std=dist[1],
                eq11_distance=float(np.mean(d)) if d else math.nan,
            )
        )
    return out


def _steps(value: float, metric: str) -> float:
    """A mean in units of its metric's resolution, rounded (−∞ for a missing one)."""
    return float(round(value / RESOLUTION[metric])) if math.isfinite(value) else -math.inf


def rank_key(c: Combination) -> tuple[float, float]:
    """What ranks a combination, best lowest: coverage, then maximum tracking distance,
    each at its resolution."""
    return (-_steps(c.coverage_mean, COVERAGE), -_steps(c.distance_mean, DISTANCE))


def ranked(combos: list[Combination]) -> list[Combination]:
    """Best first (``rank_key``); tied combinations keep their order in the grid."""
    return sorted(combos, key=rank_key)


def rank_numbers(combos: list[Combination]) -> list[int]:
    """The ranks of ``ranked`` combinations, from 1: tied ones share the rank of the
    first of them, and the next after them skips as many (1, 1, 3)."""
    out: list[int] = []
    for i, c in enumerate(combos):
        tied = i > 0 and rank_key(c) == rank_key(combos[i - 1])
        out.append(out[-1] if tied else i + 1)
    return out
