"""Import rules: the algorithms never import the simulator or file formats."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "dronetrack"
# Algorithm packages and the core modules they build on.
ALGORITHMS = ["control", "preprocess", "detect", "track", "eval"]
CORE = ["types.py", "errors.py", "geometry.py", "kinematics.py", "config.py", "pipeline.py"]
FORBIDDEN = (
    "dronetrack.sim",
    "dronetrack.io",
    "dronetrack.jobs.render",
    "dronetrack.cli.main",
    "dronetrack.viz",
)


def _imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def _modules() -> list[Path]:
    files = [SRC / name for name in CORE]
    for package in ALGORITHMS:
        files.extend(sorted((SRC / package).glob("**/*.py")))
    return files


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_algorithms_do_not_import_the_simulator_or_file_formats(path: Path) -> None:
    bad = sorted(m for m in _imports(path) if m.startswith(FORBIDDEN))
    assert not bad, f"{path.relative_to(SRC)} imports {bad}"


def test_the_rule_sees_the_packages() -> None:
    assert (SRC / "control" / "aiming.py") in _modules()
