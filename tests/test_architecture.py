"""The package's shape: each folder imports only the folders below it, no two modules
import each other (even through others), and replaying a recording never loads the
simulator."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "dronetrack"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# Bottom to top: a module may import its own layer and the layers before it.  The
# algorithms (preprocess … eval, the zones' alerts among them) take arrays and give
# arrays; the pipeline joins them; formats turn bytes into arrays; sources, actuators
# and sinks are the run loop's seams; the simulator is one more source and actuator;
# jobs assemble runs from a configuration; experiments run many; the command line
# calls them.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "interrupt", "allocator", "realtime"),
    ("geometry",),
    ("types",),
    ("seams",),
    ("config",),
    ("preprocess",),
    ("detect",),
    ("track",),
    ("classify",),
    ("control",),
    ("zones",),
    ("eval",),
    ("pipeline",),
    ("formats",),
    ("sources",),
    ("actuators",),
    ("sinks",),
    ("sim",),
    ("jobs",),
    ("experiments",),
    ("cli", "__main__"),
)
RANK = {part: i for i, layer in enumerate(LAYERS) for part in layer}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _resolve(name: str) -> str | None:
    """The package module ``name`` refers to (a name imported from a module resolves
    to the module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(module: str) -> set[str]:
    """The package modules ``module`` imports anywhere: at the top, inside functions and
    under TYPE_CHECKING."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(MODULES[module].read_text())):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
        for name in names:
            target = _resolve(name) if name.startswith("dronetrack") else None
            if target is not None and target != module and not module.startswith(target + "."):
                out.add(target)
    return out


GRAPH = {m: _imports(m) for m in MODULES}


def _part(module: str) -> str:
    """The folder or root module a module belongs to: ``dronetrack.track.kalman`` → track."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _closure(start: str) -> set[str]:
    seen = {start}
    todo = [start]
    while todo:
        for w in GRAPH[todo.pop()]:
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def _edges() -> Iterator[tuple[str, str]]:
    for module, targets in GRAPH.items():
        for target in targets:
            yield module, target


def test_every_module_has_a_layer() -> None:
    unplaced = sorted({_part(m) for m in MODULES} - set(RANK) - {"__init__"})
    assert not unplaced, f"place {unplaced} in LAYERS"


@pytest.mark.parametrize("layer", [p for layer in LAYERS for p in layer])
def test_a_folder_imports_only_the_folders_below_it(layer: str) -> None:
    bad = sorted(
        f"{m} imports {t}"
        for m, t in _edges()
        if _part(m) == layer and t != "dronetrack" and RANK[_part(t)] > RANK[layer]
    )
    assert not bad, "\n".join(bad)


def _family(module: str) -> str | None:
    """A module's family: the subpackage of its layer it lives in (``sources.livox``), or
    None for a module at the layer's top (what the layer's families share)."""
    parts = module.split(".")
    return ".".join(parts[1:3]) if len(parts) > 3 else None


# A recording holds what a device sent: its reader may decode it as the device's own
# client does (``recordings.lvx`` the Livox points, ``recordings.bag`` a ROS 2 /tf).
READS_DEVICES = {"sources.recordings"}


def test_a_family_imports_no_other_family_of_its_layer() -> None:
    """``sources.livox``, ``sources.velodyne``, ``actuators.ptu`` … each stand on their
    layer's shared modules, never on a sibling family."""
    bad = sorted(
        f"{m} imports {t}"
        for m, t in _edges()
        if (fm := _family(m)) is not None
        and (ft := _family(t)) is not None
        and fm != ft
        and fm.split(".")[0] == ft.split(".")[0]
        and fm not in READS_DEVICES
    )
    assert not bad, "\n".join(bad)


def test_the_family_rule_sees_a_family_import() -> None:
    """The rule reads the families as the layout has them (not a vacuous pass)."""
    assert _family("dronetrack.sources.livox.sdk1") == "sources.livox"
    assert _family("dronetrack.sources.live") is None
    assert "dronetrack.sources.ros2.tf" in GRAPH["dronetrack.sources.recordings.bag"]


def test_no_two_modules_of_a_folder_share_a_prefix() -> None:
    """A repeated prefix (``livox_udp``, ``livox_uri`` …) is a subpackage waiting: make it one."""
    by_folder: dict[Path, list[str]] = {}
    for path in SRC.rglob("*.py"):
        if path.stem.endswith("_pb2"):
            continue  # protoc's modules keep the names of their vendored .proto files
        if "_" in path.stem and not path.stem.startswith("__"):
            by_folder.setdefault(path.parent, []).append(path.stem.split("_")[0])
    repeated = sorted(
        f"{folder.relative_to(SRC)}: {prefix}_*"
        for folder, prefixes in by_folder.items()
        for prefix in set(prefixes)
        if prefixes.count(prefix) > 1
    )
    assert not repeated, "\n".join(repeated)


MAX_COMMAND_LINES = 60  # a command parses, calls one job and reports (docs/development.md)


def _commands() -> dict[str, int]:
    """Every ``@app.command`` function of the CLI and its length in lines, from the
    decorator's ``def`` to its last line: options, docstring and body."""
    lengths: dict[str, int] = {}
    for path in sorted((SRC / "cli").glob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.FunctionDef) and any(
                isinstance(d, ast.Call) and getattr(d.func, "attr", "") == "command"
                for d in node.decorator_list
            ):
                assert node.end_lineno is not None
                lengths[f"{path.name}:{node.name}"] = node.end_lineno - node.lineno + 1
    return lengths


def test_every_command_is_thin() -> None:
    """Options are ``Annotated`` aliases beside the command, validation and set-up are in
    config and jobs, so the command function reads on one screen."""
    commands = _commands()
    assert len(commands) >= 13, commands  # the rule sees every command
    long = {name: n for name, n in commands.items() if n > MAX_COMMAND_LINES}
    assert not long, long


def test_no_two_modules_import_each_other_even_through_others() -> None:
    assert _cycles(GRAPH) == []


def test_the_cycle_check_sees_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_the_rules_see_the_package() -> None:
    """The graph holds lazy imports too: the CLI loads its jobs inside the commands."""
    assert "dronetrack.jobs.replay" in GRAPH["dronetrack.cli.recordings"]
    assert "dronetrack.track.clock" in GRAPH["dronetrack.pipeline.core"]
    assert len(MODULES) > 100


def test_the_replay_job_imports_no_simulator_module() -> None:
    """Everything ``track`` runs, read from the source: no ``dronetrack.sim`` module."""
    reached = _closure("dronetrack.jobs.replay") | _closure("dronetrack.sources.recordings.opener")
    assert sorted(m for m in reached if m.startswith("dronetrack.sim")) == []
    assert "dronetrack.sources.recordings.bag" in reached


def test_the_live_job_imports_no_simulator_module() -> None:
    """``dronetrack live`` on a rig loads no simulator: the emulators are for tests and
    ``emulate`` only."""
    reached = _closure("dronetrack.jobs.live.run") | _closure("dronetrack.cli.live")
    assert sorted(m for m in reached if m.startswith("dronetrack.sim")) == []
    assert "dronetrack.sources.live" in reached


def _write_bag(path: Path) -> None:
    """A ROS 1 bag of 30 hand-made frames (no simulator): a 0.5 m cloud of 20 points
    moving at 2 m/s, 30 m in front of a fixed sensor, with its ground truth."""
    from dronetrack.geometry.mount import MountGeometry
    from dronetrack.sinks.bag_writer import RecordingWriter
    from dronetrack.types import Frame

    rng = np.random.default_rng(5)
    mount = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.05), (0.025, 0.0, 0.086))
    writer = RecordingWriter(path, "ros1", mount)
    pose = np.eye(4)
    pose[:3, 3] = (0.025, 0.0, 1.136)
    for k in range(30):
        t0 = 0.1 * k
        target = np.array([30.0, -3.0 + 0.2 * k, 6.0])
        points = target + rng.normal(0.0, 0.15, (20, 3)) - pose[:3, 3]
        frame = Frame(
            stamp=t0,
            duration=0.1,
            points=points,
            t=np.linspace(t0, t0 + 0.099, 20),
            line=np.zeros(20, dtype=np.uint8),
            intensity=np.full(20, 50.0, dtype=np.float32),
            pose_t=np.array([t0, t0 + 0.1]),
            poses=np.stack([pose, pose]),
        )
        writer.frame(frame, target, np.eye(3))
    writer.close()


@pytest.mark.parametrize("config", [None, "site.toml", "based"])
@pytest.mark.slow
def test_track_of_a_recording_loads_no_simulator_module(tmp_path: Path, config: str | None) -> None:
    """``dronetrack track`` in a fresh interpreter, with no configuration, a site file, and
    a file based on a named scenario: it tracks, and ``sys.modules`` holds no
    ``dronetrack.sim`` module afterwards."""
    bag = tmp_path / "flight.bag"
    _write_bag(bag)
    args = ["track", str(bag), "--background-from", "0", "--out", str(tmp_path / "run")]
    if config == "site.toml":
        args += ["--config", str(EXAMPLES / "site.toml")]
    elif config == "based":
        (tmp_path / "based.toml").write_text('base = "default"\nseed = 3\n')
        args += ["--config", str(tmp_path / "based.toml")]
    script = (
        "import json, sys\n"
        "from dronetrack.cli.main import run\n"
        f"code = run({args!r})\n"
        "print(json.dumps([code, sorted(m for m in sys.modules if m.startswith('dronetrack'))]))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    code, loaded = json.loads(done.stdout.strip().splitlines()[-1])
    assert code == 0, done.stderr
    assert "dronetrack.jobs.replay" in loaded
    assert [m for m in loaded if m.startswith("dronetrack.sim")] == []
    frames = (tmp_path / "run" / "frames.csv").read_text().splitlines()
    assert len(frames) == 1 + 30
