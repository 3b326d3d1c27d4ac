"""A comparison suite's parts: its cases (a scenario under the suite's settings), the
metrics its table shows together, and the suite itself (``experiments.compare.suites``
names them)."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Case", "MetricGroup", "Suite"]


@dataclass(frozen=True, slots=True)
class Case:
    """One column group of a paper's table: a scenario under the suite's settings."""

    label: str  # as the paper names it
    scenario: str  # a named scenario
    # controller mode: truth, fixed, or a seed 003 scan strategy; None: the scenario's own
    turret: str | None


@dataclass(frozen=True, slots=True)
class MetricGroup:
    """Metrics that table.md shows together, one row per case (and method)."""

    title: str
    metrics: tuple[str, ...]
    note: str = ""  # what the columns mean


@dataclass(frozen=True, slots=True)
class Suite:
    name: str
    title: str
    methods: tuple[str, ...]  # tracker names; for seed003, the scan strategies
    cases: tuple[Case, ...]
    metrics: tuple[str, ...]
    # (case label, method, metric) -> the seed's published figure
    paper: dict[tuple[str, str, str], float] = field(default_factory=dict)
    tracker: str | None = None  # seed003: the one tracker all strategies feed
    lockstep: bool = True  # methods share one world
    init_on_clean_view: bool = False  # Kalman filters start on the drone alone in view
    min_consecutive: int = 0  # a run counts only after this many correct frames in a row
    # The seeds' tables run their methods as published: started by their own start
    # region (or on a clean view), without dronetrack's detection-driven acquisition.
    acquisition: bool = False
    note: str = ""  # definitions of the metrics and of the set-up
    # How our set-up differs from the seed's and what that acts on.  It explains, it
    # does not rank: table.md writes every ranking from the numbers.
    setup_note: str = ""
    # table.md's layout: none, one table per case with a row per method; else one table
    # per group with a row per case (and method), for suites of many metrics
    groups: tuple[MetricGroup, ...] = ()
