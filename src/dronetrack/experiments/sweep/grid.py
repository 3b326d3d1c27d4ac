"""A parameter sweep's grid file and the runs it expands to.

    scenario = "default"   # or: recording = "flight.bag"
    duration = 20          # seconds of flight per run (optional)
    runs = 1               # seeds per combination (optional)

    [grid]
    particles = [1000, 3000]
    tracker = ["pf-delta", "pf-cv"]
    "track.sigma_pos" = [0.4, 0.5, 0.6]   # any key of config.toml, dotted

A ``[grid]`` key is either a ``simulate`` option (``particles``, ``tracker``,
``visibility``, ``drone``, ``sensor``, ``turret``, ``trajectory``) or a dotted
key of the resolved ``config.toml`` (``pipeline.tracker.sigma_pos``; ``track.``
is short for ``pipeline.tracker.``).  The runs are the Cartesian product of the
values, each with seeds ``seed, seed + 1, …, seed + runs − 1``.  A run is named
by a hash of everything that defines it, so a sweep can resume and a finished
one adds nothing when run again.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from dronetrack.config.run import (
    ScenarioConfig,
    apply_overrides,
    validate_scenario,
)
from dronetrack.config.tomlfile import format_validation_error, read_toml
from dronetrack.errors import ConfigError

__all__ = [
    "SIMULATE_OPTIONS",
    "GridSpec",
    "RunSpec",
    "check_keys",
    "expand",
    "load_grid",
    "run_config",
]

# simulate's options, as grid keys, to ``apply_overrides``' keyword arguments
SIMULATE_OPTIONS = {
    "particles": "particles",
    "tracker": "tracker",
    "visibility": "visibility",
    "drone": "drone",
    "sensor": "sensor",
    "turret": "turret_mode",
    "trajectory": "trajectory",
}
ALIASES = {"track.": "pipeline.tracker."}
Scalar = bool | int | float | str


class GridSpec(BaseModel):
    """A validated grid file."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    scenario: str | None = None
    recording: str | None = None
    duration: float | None = Field(None, gt=0)
    runs: int = Field(1, ge=1, le=10_000)
    seed: int = Field(0, ge=0)
    grid: dict[str, list[Scalar]] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _one_source(self) -> GridSpec:
        if self.scenario is not None and self.recording is not None:
            raise ValueError("give scenario or recording, not both")
        for key, values in self.grid.items():
            if not values:
                raise ValueError(f"grid key {key!r} has no values")
        return self

    @property
    def source(self) -> dict[str, str]:
        if self.recording is not None:
            return {"recording": self.recording}
        return {"scenario": self.scenario or "default"}


@dataclass(frozen=True, slots=True)
class RunSpec:
    """One run of a sweep: the source, the grid point and the seed."""

    source: dict[str, str]
    duration: float | None
    params: dict[str, Scalar]
    seed: int

    @property
    def key(self) -> str:
        """A stable name: the hash of the run's definition."""
        blob = json.dumps(
            {
                "source": self.source,
                "duration": self.duration,
                "params": self.params,
                "seed": self.seed,
            },
            sort_keys=True,
        )
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    @property
    def combination(self) -> str:
        """The grid point without the seed (runs of one combination share it)."""
        return json.dumps(self.params, sort_keys=True)


def load_grid(path: Path) -> GridSpec:
    """Read and validate a grid file; recording paths become absolute (relative to it)."""
    data = read_toml(path, "grid file")
    try:
        spec = GridSpec.model_validate(data)
    except ValidationError as err:
        raise ConfigError(format_validation_error(err, str(path))) from None
    if spec.recording is not None:
        rec = Path(spec.recording).expanduser()
        if not rec.is_absolute():
            rec = (path.parent / rec).resolve()
        spec = spec.model_copy(update={"recording": str(rec)})
    return spec


def expand(spec: GridSpec) -> list[RunSpec]:
    """Every run of the grid: the product of its values × the seeds, in a fixed order."""
    keys = list(spec.grid)
    points = itertools.product(*(spec.grid[k] for k in keys)) if keys else [()]
    return [
        RunSpec(spec.source, spec.duration, dict(zip(keys, values, strict=True)), spec.seed + r)
        for values in points
        for r in range(spec.runs)
    ]


def _set_dotted(data: dict[str, Any], key: str, value: Scalar, source: str) -> None:
    for short, full in ALIASES.items():
        if key.startswith(short):
            key = full + key[len(short) :]
    parts = key.split(".")
    node: Any = data
    for part in parts[:-1]:
        if not isinstance(node, dict) or part not in node or not isinstance(node[part], dict):
            raise ConfigError(f"{source}: no section {part!r} in the configuration")
        node = node[part]
    if parts[-1] not in node:
        raise ConfigError(f"{source}: unknown key {parts[-1]!r}")
    node[parts[-1]] = value


def run_config(base: ScenarioConfig, run: RunSpec, source: str | None = None) -> ScenarioConfig:
    """``base`` with the run's seed, duration and grid values applied and validated; a
    bad key or value is a ConfigError naming ``source`` (default: the grid point)."""
    where = source or f"grid point {json.dumps(run.params, sort_keys=True)}"
    options: dict[str, Any] = {
        SIMULATE_OPTIONS[k]: (Path(str(v)) if k == "trajectory" else v)
        for k, v in run.params.items()
        if k in SIMULATE_OPTIONS
    }
    cfg = apply_overrides(base, seed=run.seed, duration=run.duration, **options, source=where)
    dotted = {k: v for k, v in run.params.items() if k not in SIMULATE_OPTIONS}
    if not dotted:
        return cfg
    data = cfg.model_dump()
    for key, value in dotted.items():
        _set_dotted(data, key, value, where)
    return validate_scenario(data, where)


def _check_name(key: str, value: Scalar, where: str) -> None:
    """A drone or sensor name the configuration's validation leaves to the run: an
    unknown one fails here, once, rather than in every run."""
    from dronetrack.config.rig import target_spec
    from dronetrack.sim.sensors import make_sensor

    try:
        if key == "drone":
            target_spec(str(value))
        elif key == "sensor":
            make_sensor(str(value))
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None


def check_keys(spec: GridSpec, base: ScenarioConfig, grid: Path | str = "grid file") -> None:
    """Fail before any run starts if a grid key or value does not fit the configuration:
    a ConfigError naming the ``grid`` file, the key and the value."""
    for key, values in spec.grid.items():
        for value in values:
            where = f"{grid}: [grid] {key} = {json.dumps(value)}"
            run_config(base, RunSpec(spec.source, spec.duration, {key: value}, spec.seed), where)
            _check_name(key, value, where)


def base_config(spec: GridSpec) -> ScenarioConfig:
    """The configuration the grid varies: the named scenario, or the recording's own."""
    if spec.recording is not None:
        from dronetrack.jobs.replay import recording_config
        from dronetrack.sources.recordings.opener import open_recording

        return recording_config(open_recording(Path(spec.recording)), None)
    from dronetrack.config.scenarios import get_scenario

    return get_scenario(spec.scenario or "default")


def planned_runs(grid: Path) -> list[RunSpec]:
    """The runs of the grid file ``grid``, its keys checked against the configuration
    it varies (ConfigError names a bad file, key or value)."""
    spec = load_grid(grid)
    check_keys(spec, base_config(spec), grid)
    return expand(spec)
