"""``--help`` as a new user reads it: at 80 columns and on a wide terminal, nothing is
cut, paragraphs reflow, every default is shown the same way, the valid names are
listed and flags take no value; and the command tables of the README and of the
commands page (docs/commands.md) name every command."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import pytest
import typer

from dronetrack.cli.app import app
from dronetrack.cli.main import run
from dronetrack.config.rig import TARGETS
from dronetrack.sim.sensors import SENSOR_NAMES

ROOT = Path(__file__).resolve().parents[2]
# Each file's command table: the section that holds it.
COMMAND_TABLES = {ROOT / "README.md": "Commands", ROOT / "docs" / "commands.md": "Overview"}
GROUP = typer.main.get_group(app)
COMMANDS = list(GROUP.commands)
EVERY_HELP = [[], *([name] for name in COMMANDS)]  # the app's own help, then each command's


def _help(
    argv: list[str],
    width: int,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> str:
    """The help ``argv`` prints on a terminal ``width`` columns wide."""
    monkeypatch.setenv("COLUMNS", str(width))
    assert run([*argv, "--help"]) == 0
    return capsys.readouterr().out


def _rows(text: str) -> dict[str, str]:
    """Each option's row in the help's panels, its wrapped lines joined, by its first
    name; an option's name starts a line, its wrapped text is indented further."""
    rows: dict[str, list[str]] = {}
    current: str | None = None
    for line in text.splitlines():
        if not line.startswith("│"):
            current = None
            continue
        start = line.find("--")
        if 0 < start <= 5:
            found = re.match(r"--[\w-]+", line[start:])
            assert found is not None
            current = found.group(0)
            rows[current] = []
        if current is not None:
            rows[current].append(line.strip("│ "))
    return {name: " ".join(parts) for name, parts in rows.items()}


def _description(text: str) -> list[list[str]]:
    """The paragraphs between the usage line and the first panel, as their lines."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if "Usage:" in line) + 1
    end = next(i for i, line in enumerate(lines) if line.startswith("╭"))
    paragraphs: list[list[str]] = [[]]
    for line in lines[start:end]:
        if line.strip():
            paragraphs[-1].append(line.strip())
        elif paragraphs[-1]:
            paragraphs.append([])
    return [p for p in paragraphs if p]


@pytest.mark.parametrize("argv", EVERY_HELP, ids=lambda a: " ".join(a) or "dronetrack")
def test_nothing_in_the_help_is_cut_at_80_columns(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """No ellipsis, and every word of every option's and argument's help is there whole
    (a long word in a narrow column is cut with '…'; a [word] read as markup vanishes)."""
    text = _help(argv, 80, monkeypatch, capsys)
    assert "…" not in text
    command = GROUP.commands[argv[0]] if argv else GROUP
    for param in command.get_params(typer.Context(command)):
        for word in (getattr(param, "help", None) or "").split():
            assert word in text, (param.name, word)


@pytest.mark.parametrize("width", [80, 200])
@pytest.mark.parametrize("argv", EVERY_HELP, ids=lambda a: " ".join(a) or "dronetrack")
def test_help_paragraphs_break_only_where_the_line_is_full(
    argv: list[str], width: int, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A line of a paragraph ends only because the next word would not fit on it (the
    text is indented by one column on either side), at 80 columns and at 200."""
    text = _help(argv, width, monkeypatch, capsys)
    for paragraph in _description(text):
        for line, following in itertools.pairwise(paragraph):
            assert len(line) + 1 + len(following.split()[0]) > width - 2, (line, following)


def test_each_command_is_one_line_in_the_list_on_a_wide_terminal(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    text = _help([], 200, monkeypatch, capsys)
    panel = text.split("Commands", 1)[1].split("╰", 1)[0].splitlines()[1:]
    names = [line.strip("│ ").split()[0] for line in panel]
    assert names == COMMANDS


@pytest.mark.parametrize("argv", EVERY_HELP, ids=lambda a: " ".join(a) or "dronetrack")
def test_defaults_are_shown_one_way(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every option with a default value shows it as [default: …]; no help states one
    in prose, '(default: …)', or in brackets of its own, '[3]'."""
    text = _help(argv, 80, monkeypatch, capsys)
    rows = _rows(text)
    command = GROUP.commands[argv[0]] if argv else GROUP
    for param in command.get_params(typer.Context(command)):
        if not isinstance(param, typer.core.TyperOption) or param.opts[0] not in rows:
            continue
        row = rows[param.opts[0]]
        assert "(default:" not in row, row
        assert not re.search(r"\[\d[\d,.]*( s)?\]", row), row
        valued = param.default is not None and not (param.is_flag and not param.secondary_opts)
        if valued or isinstance(param.show_default, str):
            assert "[default:" in row, row


def test_the_overrides_of_a_scenario_show_their_default(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = _rows(_help(["simulate"], 80, monkeypatch, capsys))
    for name in ("--tracker", "--turret", "--seed", "--drone", "--sensor", "--duration"):
        assert "[default:" in rows[name], name


def test_bench_shows_every_default_as_the_others_do(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from dronetrack.experiments.bench import FULL, LIVE_FULL

    rows = _rows(_help(["bench"], 80, monkeypatch, capsys))
    flags = {"--quick", "--live", "--ros2", "--sapient", "--help"}
    for name, row in rows.items():
        if name not in flags:
            assert "[default:" in row, row
    assert f"[default: ({FULL.rounds};" in rows["--rounds"]
    assert f"[default: ({LIVE_FULL.soak_s:g} s;" in rows["--soak-s"]


@pytest.mark.parametrize("command", ["simulate", "render", "record"])
def test_drone_and_sensor_list_every_registered_name(
    command: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = _rows(_help([command], 80, monkeypatch, capsys))
    assert len(TARGETS) > 1
    assert len(SENSOR_NAMES) > 1
    for name in TARGETS:
        assert re.search(rf"\b{re.escape(name)}\b", rows["--drone"]), name
    for name in SENSOR_NAMES:
        assert re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", rows["--sensor"]), name


@pytest.mark.parametrize("argv", EVERY_HELP, ids=lambda a: " ".join(a) or "dronetrack")
def test_flags_show_no_value_placeholder(
    argv: list[str], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A flag takes no value (``--verbose true`` is an error), so its help shows none."""
    assert "<bool>" not in _help(argv, 80, monkeypatch, capsys)


def test_a_flag_is_given_without_a_value(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["scenarios", "--verbose"]) == 0
    assert run(["scenarios", "-v"]) == 0
    capsys.readouterr()
    assert run(["scenarios", "--verbose", "true"]) == 2
    assert capsys.readouterr().err.startswith("error: ")


@pytest.mark.parametrize("path", list(COMMAND_TABLES), ids=lambda p: p.name)
def test_the_command_tables_name_every_command(path: Path) -> None:
    text = path.read_text()
    section = text.split(f"\n## {COMMAND_TABLES[path]}\n", 1)[1].split("\n#", 1)[0]
    named = set(re.findall(r"^\| `dronetrack ([\w-]+)", section, flags=re.MULTILINE))
    assert named >= set(COMMANDS), sorted(set(COMMANDS) - named)
