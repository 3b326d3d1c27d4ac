"""Every shell example of the README and the documentation is tested.

The fast tier reads every ``bash``, ``console`` and ``sh`` block of ``README.md`` and
``docs/**/*.md``: each ``dronetrack`` command line must parse against the real command
line interface (click's ``make_context``, which validates the options without running
the command), and the other lines are checked as far as is sensible (the files they
name exist, the extras they install are defined, the refresh script's options parse).
It also checks the pages against ``mkdocs.yml``'s navigation, the generated results
against what the pages include, and the TOML examples against the loaders.

The slow tier runs the examples that can run here, page by page, in a temporary
folder with a copy of ``examples/``: each ``dronetrack`` command shortened where the
command line allows (``--duration``, and ``--runs 1`` or ``--quick``), paths under
``/tmp/`` moved into the folder, an emulator (``dronetrack emulate``) kept running in
the background for the commands after it, ROS 2 on a loopback-only DDS configuration.
``NOT_RUN`` and ``NOT_RUN_PROGRAMS`` list what cannot run here, with the reason.
"""

from __future__ import annotations

import importlib.util
import os
import re
import select
import shlex
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import pytest
import typer

import dronetrack.cli.main  # noqa: F401  (registers every command on the app)
from dronetrack.cli.app import app
from dronetrack.config.run import load_scenario_file
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.experiments.sweep.grid import expand, load_grid
from ros2_helpers import CONFIG as LOOPBACK_DDS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
RESULTS = DOCS / "results"
# The pages and the README; docs/results/ holds generated tables, not examples.
PAGES = [
    ROOT / "README.md",
    *sorted(p for p in DOCS.rglob("*.md") if RESULTS not in p.parents),
]
SHELL = {"bash", "console", "sh", "shell"}

QUICK_START = (
    'python3 -m pip install -e . && dronetrack simulate\npython3 -m pip install -e ".[test]" '
    "&& python3 -m pytest"
)

# Examples that cannot run here, each with the reason (the fast tier still parses them).
NOT_RUN = {
    "dronetrack info livox://192.168.1.3": "a Livox SDK 1 LiDAR on the rig's network",
    "dronetrack info livox2://192.168.1.12": "a Livox Mid-360 on the rig's network",
    "dronetrack info velodyne://192.168.1.100:2368": "a VLP-16 sending to the rig's address",
    'dronetrack info "dynamixel:///dev/ttyUSB0?baud=1000000&pan=1&tilt=2"': "servos on a bus",
    "dronetrack info ptu:///dev/ttyUSB0": "a FLIR PTU on a serial port",
    "dronetrack info ptu://192.168.1.110:4000": "a FLIR PTU on the rig's network",
    "dronetrack live examples/site.toml --lidar livox://192.168.1.3 --turret "
    '"dynamixel:///dev/ttyUSB0?baud=1000000&pan=1&tilt=2" --duration 120 --out runs/site-1': (
        "an Avia and servos on a rig"
    ),
    "dronetrack live examples/site_ptu.toml --lidar livox://192.168.1.3 --turret "
    "ptu:///dev/ttyUSB0 --duration 120 --out runs/site-ptu-1": "an Avia and a FLIR PTU on a rig",
    "dronetrack live walk-line --lidar velodyne://2368 --turret none --duration 120 "
    "--out runs/vlp16-1": "a VLP-16 on a rig (the emulated one is run above it on the page)",
    "python3 docs/results/refresh.py": (
        "the full refresh takes about an hour and rewrites docs/results/; the --quick "
        "example runs the same code"
    ),
    "python3 docs/results/refresh.py --suites multi,simulate": (
        "rewrites docs/results/; the --quick example runs the same code"
    ),
}
# Programs whose lines are checked, not run, with the reason.
NOT_RUN_PROGRAMS = {
    "pip": "installs into the environment the tests run in (tests/cli/test_fresh_install.py "
    "covers a fresh install)",
    "pytest": "the test suite itself",
    "ruff": "CI runs it (.ci/run)",
    "mypy": "CI runs it (.ci/run)",
    "mkdocs": "CI runs it (.ci/run)",
    ".ci/run": "CI itself",
    "benchmarks": "timing runs of minutes each; dronetrack bench --quick runs the same code",
}

# The slow tier's shortening.
SHORT_DURATION = "2"
SHORTENED = {"simulate", "record", "render", "emulate", "live", "compare"}
TIMEOUT_S = 600.0


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # of the opening fence, from 1
    lang: str
    text: str


@dataclass(frozen=True)
class Example:
    block: Block
    command: str  # one logical command line, continuations joined

    @property
    def where(self) -> str:
        return f"{self.block.page.relative_to(ROOT)}:{self.block.line}"

    def parts(self) -> list[list[str]]:
        """The simple commands of the line, split at ``&&``, ``||``, ``;`` and ``|``."""
        out: list[list[str]] = [[]]
        for token in shlex.split(self.command, comments=True):
            if token in ("&&", "||", ";", "|"):
                out.append([])
            else:
                out[-1].append(token)
        return [p for p in out if p]


FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>```+|~~~+)\s*(?P<lang>[\w+-]*)")


def blocks(page: Path) -> Iterator[Block]:
    """The fenced code blocks of a page, with their language."""
    lines = page.read_text().splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = len(m["indent"]), m["fence"], m["lang"]
        body = []
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            body.append(lines[j][indent:])
            j += 1
        yield Block(page, i + 1, lang, "\n".join(body))
        i = j + 1


def commands(block: Block) -> Iterator[str]:
    """A shell block's command lines: in a console block those after a ``$ `` prompt
    (the rest is output), elsewhere every line that is not a comment."""
    pending = ""
    for raw in block.text.splitlines():
        line = raw.rstrip()
        if not pending:
            if block.lang == "console":
                if not line.startswith("$ "):
                    continue
                line = line[2:]
            if not line.strip() or line.lstrip().startswith("#"):
                continue
        if line.endswith("\\"):
            pending += line[:-1].rstrip() + " "
            continue
        yield (pending + line).strip()
        pending = ""
    assert not pending, f"{block.page}:{block.line}: a continuation line ends the block"


def examples(page: Path) -> list[Example]:
    return [Example(b, c) for b in blocks(page) if b.lang in SHELL for c in commands(b)]


ALL = [e for page in PAGES for e in examples(page)]


def _id(e: Example) -> str:
    return f"{e.where}:{e.command[:60]}"


# --- the fast tier ----------------------------------------------------------------------


def parse_dronetrack(args: list[str]) -> str:
    """Parse ``dronetrack ARGS`` against the real command line without running it;
    return the command's name.  Raises click's usage errors."""
    group = typer.main.get_command(app)
    assert args, "no command"
    assert not args[0].startswith("-"), f"a command name first: {args}"
    with group.make_context("dronetrack", list(args)) as ctx:
        name, cmd, rest = group.resolve_command(ctx, list(args))
        assert cmd is not None, args
        assert name is not None, args
        with cmd.make_context(name, rest, parent=ctx):
            pass
    return name


def _extras() -> set[str]:
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return set(data["project"]["optional-dependencies"])


def _load_refresh() -> ModuleType:
    spec = importlib.util.spec_from_file_location("refresh", RESULTS / "refresh.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _program(part: list[str]) -> str:
    """What a simple command runs: ``dronetrack``, ``pip``, ``pytest``, ``ruff``,
    ``mypy``, ``mkdocs``, ``.ci/run``, ``benchmarks`` or ``script`` (a python3 file)."""
    if part[0] == "dronetrack":
        return "dronetrack"
    if part[0] in ("python3", "python"):
        if len(part) > 2 and part[1] == "-m":
            return part[2]
        assert len(part) > 1, part
        return "benchmarks" if part[1].startswith("benchmarks/") else "script"
    return part[0]


def check_part(part: list[str]) -> None:
    program = _program(part)
    if program == "dronetrack":
        parse_dronetrack(part[1:])
    elif program == "pip":
        assert part[3] == "install", part
        for arg in part[4:]:
            if arg.startswith("-"):
                continue
            m = re.fullmatch(r"(?:\.|dronetrack)(?:\[([\w,-]+)\])?", arg)
            assert m, f"pip installs the project or its extras only: {arg}"
            extras = set(m[1].split(",")) if m[1] else set()
            assert extras <= _extras(), sorted(extras - _extras())
    elif program in ("pytest", "ruff", "mypy"):
        for arg in part[3:]:
            if "/" in arg or arg in ("src", "tests", "benchmarks", "docs"):
                assert (ROOT / arg).exists(), arg
    elif program == "mkdocs":
        assert (ROOT / "mkdocs.yml").is_file()
        assert part[3] in ("build", "serve"), part
    elif program == ".ci/run":
        assert os.access(ROOT / ".ci" / "run", os.X_OK)
    elif program == "benchmarks":
        assert (ROOT / part[1]).is_file(), part[1]
    elif program == "script":
        assert part[1] == "docs/results/refresh.py", f"an unknown script: {part[1]}"
        _load_refresh().parse(part[2:])
    else:
        pytest.fail(f"an example runs {part[0]!r}, which tests/test_docs.py does not know")


def test_the_pages_have_shell_examples() -> None:
    assert len(ALL) > 50
    assert {e.block.page.name for e in ALL} >= {"README.md", "commands.md", "live.md"}


@pytest.mark.parametrize("example", ALL, ids=_id)
def test_every_shell_example_is_valid(example: Example) -> None:
    for part in example.parts():
        try:
            check_part(part)
        except (Exception, SystemExit) as err:  # click's usage errors, argparse's exit
            pytest.fail(f"{example.where}: {example.command}\n{type(err).__name__}: {err}")


def test_the_not_run_lists_name_examples_that_exist() -> None:
    shown = {e.command for e in ALL}
    assert set(NOT_RUN) <= shown, sorted(set(NOT_RUN) - shown)
    programs = {_program(p) for e in ALL for p in e.parts()}
    assert set(NOT_RUN_PROGRAMS) <= programs, sorted(set(NOT_RUN_PROGRAMS) - programs)


def test_the_readme_quick_start_is_its_first_block() -> None:
    first = next(blocks(ROOT / "README.md"))
    assert first.lang == "bash"
    assert first.text.strip() == QUICK_START


def test_the_readme_says_what_is_tested_and_what_ctrl_c_does() -> None:
    text = " ".join((ROOT / "README.md").read_text().split())
    assert "tested against emulators" in text or "tested against emulators of" in text
    assert "not tested against hardware" in text
    assert "exit code 130" in text


def test_the_readme_links_to_files_that_exist() -> None:
    text = (ROOT / "README.md").read_text()
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
        if "://" in target:
            continue
        assert (ROOT / target).exists(), target


def _nav_pages() -> set[str]:
    text = (ROOT / "mkdocs.yml").read_text()
    nav = text.split("\nnav:\n", 1)[1]
    return set(re.findall(r"([\w/.-]+\.md)\s*$", nav, flags=re.MULTILINE))


def test_every_page_is_in_the_navigation() -> None:
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md") if RESULTS not in p.parents}
    nav = _nav_pages()
    assert pages == nav, (sorted(pages - nav), sorted(nav - pages))


def _includes() -> set[str]:
    found = set()
    for page in PAGES:
        found |= set(re.findall(r'^--8<-- "([^"]+)"', page.read_text(), flags=re.MULTILINE))
    return found


def test_the_pages_include_every_generated_table_and_nothing_else() -> None:
    refresh = _load_refresh()
    written = {f"docs/results/{f}" for part in refresh.PARTS for f in refresh.files_of(part)}
    assert _includes() == written
    for name in written:
        assert (ROOT / name).is_file(), f"{name} is missing: python3 docs/results/refresh.py"


def test_the_refresh_script_knows_every_compare_suite() -> None:
    from dronetrack.experiments.compare.suites import SUITES

    assert set(_load_refresh().SUITES) == set(SUITES)


def test_the_refresh_script_refuses_an_unknown_part() -> None:
    with pytest.raises(SystemExit):
        _load_refresh().parse(["--suites", "nonsense"])
    opts = _load_refresh().parse(["--quick", "--suites", "multi"])
    assert (opts.runs, opts.duration, opts.parts) == (1, 2.0, ["multi"])


def test_the_toml_examples_load(tmp_path: Path) -> None:
    """A scenario example (``base = ...``) loads as a scenario file, a grid example
    (``[grid]``) as a sweep grid."""
    seen = 0
    for page in PAGES:
        for block in blocks(page):
            if block.lang != "toml":
                continue
            path = tmp_path / f"{page.stem}-{block.line}.toml"
            path.write_text(block.text + "\n")
            if block.text.lstrip().startswith("base ="):
                load_scenario_file(path, SCENARIOS)
            elif "[grid]" in block.text:
                assert expand(load_grid(path))
            else:
                pytest.fail(f"{page}:{block.line}: a TOML example of an unknown kind")
            seen += 1
    assert seen >= 2


# --- the slow tier ----------------------------------------------------------------------


def _shortened(args: list[str], tmp: Path) -> list[str]:
    """``dronetrack ARGS`` as the slow tier runs it: shorter, and /tmp/ moved into tmp."""
    args = [a.replace("/tmp/", f"{tmp}/") for a in args]
    name = args[1]
    if name in SHORTENED and not {"--duration", "-d"} & set(args):
        args += ["--duration", SHORT_DURATION]
    if name == "compare":
        if "--runs" in args:
            args[args.index("--runs") + 1] = "1"
        else:
            args += ["--runs", "1"]
    if name == "bench" and "--quick" not in args:
        args.append("--quick")
    return args


# What a command run in the background for the commands after it on the page says
# when it is ready for them.
BACKGROUND = {"emulate": b"turret:", "sapient-listen": b"listening on"}


class Background:
    """``dronetrack emulate`` or ``sapient-listen`` running for the commands after it on
    the page."""

    def __init__(self, args: list[str], cwd: Path, env: dict[str, str]) -> None:
        marker = BACKGROUND[args[1]]
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "dronetrack", *args[1:]],
            cwd=cwd,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )
        self.out = b""
        deadline = time.monotonic() + 120.0
        assert self.proc.stdout is not None
        while marker not in self.out and time.monotonic() < deadline:
            ready, _, _ = select.select([self.proc.stdout], [], [], 0.5)
            if ready:
                got = os.read(self.proc.stdout.fileno(), 4096)
                if not got:
                    break
                self.out += got
        assert marker in self.out, (args, self.out.decode(), self.proc.poll())

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        if self.proc.stdout is not None:
            self.out += self.proc.stdout.read()  # what it said after it was ready
            self.proc.stdout.close()
        assert self.proc.returncode in (0, 130), (self.proc.returncode, self.out.decode())


def _env(tmp: Path) -> dict[str, str]:
    dds = tmp / "cyclonedds.xml"
    dds.write_text(LOOPBACK_DDS)  # loopback-only DDS for the ROS 2 examples
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT / "src"), env.get("PYTHONPATH")) if p)
    env.update(MPLBACKEND="Agg", PYTHONUNBUFFERED="1", CYCLONEDDS_URI=dds.as_uri())
    env.pop("ROS_DOMAIN_ID", None)
    return env


def _runnable(page: Path) -> list[Example]:
    out = []
    for e in examples(page):
        if e.command in NOT_RUN:
            continue
        if any(_program(p) in NOT_RUN_PROGRAMS for p in e.parts()):
            continue
        out.append(e)
    return out


RUN_PAGES = [p for p in PAGES if _runnable(p)]


@pytest.mark.slow
@pytest.mark.parametrize("page", RUN_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_examples_run(page: Path, tmp_path: Path) -> None:
    """Every example of the page that can run here runs and exits 0, in order, in one
    folder (an example may use what one before it wrote)."""
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = _env(tmp_path)
    running: dict[str, Background] = {}  # by command: one emulator, one fusion node
    try:
        for example in _runnable(page):
            for part in example.parts():
                if _program(part) == "script":
                    args = [sys.executable, str(ROOT / part[1])]
                    args += [a.replace("/tmp/", f"{tmp_path}/") for a in part[2:]]
                else:
                    short = _shortened(part, tmp_path)
                    if short[1] in BACKGROUND:
                        if short[1] in running:
                            running.pop(short[1]).stop()
                        running[short[1]] = Background(short, tmp_path, env)
                        continue
                    args = [sys.executable, "-m", "dronetrack", *short[1:]]
                done = subprocess.run(
                    args,
                    cwd=tmp_path,
                    env=env,
                    capture_output=True,
                    text=True,
                    timeout=TIMEOUT_S,
                    check=False,
                )
                assert done.returncode == 0, (
                    f"{example.where}: {' '.join(args)}\n{done.stdout[-2000:]}\n"
                    f"{done.stderr[-3000:]}"
                )
    finally:
        for background in running.values():
            background.stop()
