"""table.md: run options, and ranking sentences written from the rows (hand-built rows)."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.config.scenarios import get_scenario
from dronetrack.experiments.compare.ranking import (
    Row,
    Verdict,
    combined_standard_error,
    judge,
    pair_lines,
    ranking_differences,
    ranking_lines,
)
from dronetrack.experiments.compare.run_files import run_dir
from dronetrack.experiments.compare.runner import RunMetrics
from dronetrack.experiments.compare.suites import SUITES, get_suite
from dronetrack.experiments.compare.tables import table_markdown

NAN = math.nan
INDOOR = get_suite("seed000-indoor")
LABELS = ("horizontal", "vertical", "fast", "lost and found")


def _row(
    scenario: str,
    method: str,
    mean: float,
    std: float,
    *,
    metric: str = "rmse_m",
    paper: float = NAN,
    runs: int = 5,
    finite: int | None = None,
) -> Row:
    return Row(scenario, method, metric, mean, std, paper, runs, runs if finite is None else finite)


def _pf_rows(cv: dict[str, float], delta: dict[str, float], std: float = 0.005) -> list[Row]:
    rows = []
    for label in LABELS:
        rows.append(_row(label, "pf-cv", cv[label], std))
        rows.append(_row(label, "pf-delta", delta[label], std))
    return rows


def _md(rows: list[Row], runs: int = 5, duration: float | None = None) -> str:
    return table_markdown(INDOOR, rows, runs=runs, duration=duration, methods=("pf-cv", "pf-delta"))


# --- verdicts -------------------------------------------------------------------------


def test_combined_standard_error_of_two_means() -> None:
    a = _row("x", "a", 1.0, 0.3, runs=9)
    b = _row("x", "b", 2.0, 0.4, runs=16)
    assert combined_standard_error(a, b) == pytest.approx(math.sqrt(0.01 + 0.01))
    # Fewer than two runs with a number: no spread.
    assert math.isnan(combined_standard_error(a, _row("x", "b", 2.0, NAN, runs=5, finite=1)))


def test_a_difference_counts_only_beyond_the_combined_standard_error() -> None:
    # Five runs of std 0.1 each: combined standard error √(2 · 0.01 / 5) = 0.063.
    a = _row("x", "a", 1.0, 0.1)
    assert judge(a, _row("x", "b", 1.05, 0.1)) == Verdict.LEVEL
    assert judge(a, _row("x", "b", 1.2, 0.1)) == Verdict.AHEAD  # lower RMSE is better
    assert judge(_row("x", "b", 1.2, 0.1), a) == Verdict.BEHIND
    cov = _row("x", "a", 90.0, 1.0, metric="coverage_pct")
    assert judge(cov, replace(cov, method="b", mean=50.0)) == Verdict.AHEAD  # higher is better
    one = _row("x", "a", 1.0, NAN, runs=1)
    assert judge(one, replace(one, method="b", mean=2.0)) == Verdict.UNJUDGED
    assert judge(one, replace(one, method="b")) == Verdict.LEVEL  # equal numbers
    assert judge(a, _row("x", "b", NAN, NAN, finite=0)) == Verdict.MISSING


# --- the issue: a pair that wins in one scenario and trails in the others --------------


def test_a_method_that_wins_once_is_not_said_to_trail_everywhere() -> None:
    cv = {"horizontal": 0.080, "vertical": 0.085, "fast": 0.156, "lost and found": 0.643}
    delta = {"horizontal": 0.054, "vertical": 0.119, "fast": 0.132, "lost and found": 0.292}
    md = _md(_pf_rows(cv, delta))
    assert "everywhere" not in md.lower()
    assert "trails" not in md
    assert "in all 4 scenarios" not in md
    assert (
        "- rmse_m, pf-cv vs pf-delta: pf-cv ahead in vertical (0.085 vs 0.119); "
        "pf-delta ahead in horizontal (0.08 vs 0.054), fast (0.156 vs 0.132), "
        "lost and found (0.643 vs 0.292)\n"
    ) in md
    assert (
        "- vertical, rmse_m (lower is better): "
        "pf-cv 0.085 ± 0.005, ahead of pf-delta 0.119 ± 0.005\n"
    ) in md


def test_a_method_ahead_in_every_scenario_is_said_so() -> None:
    cv = {"horizontal": 0.080, "vertical": 0.150, "fast": 0.156, "lost and found": 0.643}
    delta = {"horizontal": 0.054, "vertical": 0.119, "fast": 0.132, "lost and found": 0.292}
    assert pair_lines(_pf_rows(cv, delta)) == [
        "rmse_m (lower is better), in all 4 scenarios: pf-delta ahead of pf-cv"
    ]
    # One scenario within the spread: no longer "all".
    cv["vertical"] = 0.121
    (line,) = pair_lines(_pf_rows(cv, delta))
    assert "all 4" not in line
    assert "level in vertical (0.121 vs 0.119)" in line


def test_means_within_the_spread_are_level_not_ranked() -> None:
    rows = [_row("vertical", "pf-cv", 0.085, 0.05), _row("vertical", "pf-delta", 0.09, 0.05)]
    assert ranking_lines(rows) == [
        "vertical, rmse_m (lower is better): pf-cv 0.085 ± 0.05, level with pf-delta 0.09 ± 0.05"
    ]


def test_higher_is_better_ranks_the_largest_first() -> None:
    rows = [
        _row("fast", "pf-cv", 23.0, 2.0, metric="coverage_pct"),
        _row("fast", "pf-delta", 79.0, 3.0, metric="coverage_pct"),
    ]
    assert ranking_lines(rows) == [
        "fast, coverage_pct (higher is better): pf-delta 79 ± 3, ahead of pf-cv 23 ± 2"
    ]


def test_one_run_orders_by_the_means_and_claims_nothing() -> None:
    cv = {"horizontal": 0.080, "vertical": 0.085, "fast": 0.156, "lost and found": 0.643}
    delta = {"horizontal": 0.054, "vertical": 0.119, "fast": 0.132, "lost and found": 0.292}
    rows = [replace(r, std=NAN, runs=1, finite=1) for r in _pf_rows(cv, delta)]
    md = _md(rows, runs=1)
    bullets = [line for line in md.splitlines() if line.startswith("- ")]
    assert not [line for line in bullets if "ahead" in line or "level" in line]
    assert "vertical, rmse_m (lower is better): pf-cv 0.085, then pf-delta 0.119" in md
    assert "pf-cv lower, unjudged, in vertical (0.085 vs 0.119)" in md
    assert "No method has two runs with a number" in md


def test_runs_without_a_number_are_named_not_ranked() -> None:
    rows = [
        _row("fast", "ekf-catalano", NAN, NAN, finite=0),
        _row("fast", "pf-cv", 0.3, 0.01, finite=3),
        _row("fast", "pf-delta", 0.1, 0.01),
        _row("vertical", "ekf-catalano", 0.2, 0.01),
        _row("vertical", "pf-cv", 0.3, 0.01),
        _row("vertical", "pf-delta", 0.1, 0.01),
    ]
    lines = ranking_lines(rows)
    assert lines[0] == (
        "fast, rmse_m (lower is better): pf-delta 0.1 ± 0.01, "
        "ahead of pf-cv 0.3 ± 0.01 (3 of 5 runs); no number: ekf-catalano"
    )
    pairs = pair_lines(rows)
    assert "rmse_m, ekf-catalano vs pf-cv: ekf-catalano ahead in vertical (0.2 vs 0.3); " in (
        "\n".join(pairs)
    )
    assert any("no number in fast (n/a vs 0.3)" in p for p in pairs)
    assert not any("ekf-catalano" in p and "all 2" in p for p in pairs)


def test_interval_ends_are_not_ranked() -> None:
    rows = [
        _row(s, m, v, 0.01, metric="rmse_ci_low_m")
        for s in ("fast", "vertical")
        for m, v in (("pf-cv", 0.1), ("pf-delta", 0.3))
    ]
    assert ranking_lines(rows) == []
    assert pair_lines(rows) == []
    assert ranking_differences([replace(r, paper=1.0 / r.mean) for r in rows]) == []


def test_ranking_differences_give_both_orders_and_how_sure_ours_is() -> None:
    ours_clear = [
        _row("x", "a", 0.2, 0.01, paper=0.05),
        _row("x", "b", 0.1, 0.01, paper=0.06),
    ]
    assert ranking_differences(ours_clear) == [
        "x, rmse_m (lower is better): ours b 0.1 ± 0.01, ahead of a 0.2 ± 0.01; "
        "seed a 0.05, b 0.06.  Swapped against the seed: b 0.1 ahead of a 0.2"
    ]
    ours_level = [
        _row("x", "a", 0.11, 0.1, paper=0.05),
        _row("x", "b", 0.1, 0.1, paper=0.06),
    ]
    (line,) = ranking_differences(ours_level)
    assert line.endswith("Swapped against the seed: b 0.1 level with a 0.11")
    same_order = [replace(r, paper=1.0 - r.paper) for r in ours_level]
    assert ranking_differences(same_order) == []


# --- run options -----------------------------------------------------------------------


def _full(label: str) -> str:
    (case,) = [c for c in INDOOR.cases if c.label == label]
    return f"{label} {get_scenario(case.scenario).duration_s:g} s"


def test_options_header_lists_runs_duration_methods_and_seeds() -> None:
    md = table_markdown(INDOOR, [], runs=3, duration=10.0, methods=("pf-cv", "pf-delta"))
    assert "- `--runs 3`: seeds 0-2 (run r of every method is seed r)\n" in md
    assert "- `--duration 10` s: shortened" in md
    assert "- methods: pf-cv, pf-delta (`--methods`; not run: ekf-catalano, ekf-dogru)\n" in md
    assert "**Shortened runs.**  These flights were cut to 10 s (" in md
    for label in LABELS:
        assert _full(label) in md
    assert "seed's figures in brackets come from full-length flights" in md


def test_a_full_length_run_has_no_warning() -> None:
    md = table_markdown(INDOOR, [], runs=1, duration=None, methods=INDOOR.methods)
    assert "- `--runs 1`: seed 0 " in md
    assert "- `--duration` not given: full length" in md
    assert "(all of the suite's)" in md
    assert "Shortened" not in md
    longest = max(get_scenario(c.scenario).duration_s for c in INDOOR.cases)
    md = table_markdown(INDOOR, [], runs=2, duration=longest, methods=INDOOR.methods)
    assert "seeds 0 and 1" in md
    assert "Shortened" not in md


def test_the_warning_names_only_the_flights_cut_short() -> None:
    md = table_markdown(INDOOR, [], runs=5, duration=60.0, methods=INDOOR.methods)
    warning = next(line for line in md.splitlines() if line.startswith("**Shortened"))
    assert _full("fast") in warning
    assert _full("lost and found") in warning
    assert "horizontal" not in warning
    assert "vertical" not in warning


# --- the canned notes explain, they do not rank ----------------------------------------

_RANKING_WORDS = re.compile(
    r"\b(trails?|beats?|best|worst|lowest|highest|most accurate|more accurate|"
    r"less accurate|better|worse|ahead|behind|outperforms?|wins?|ties?|rank\w*|"
    r"everywhere|as there|holds on longer|does worse|does better)\b",
    re.IGNORECASE,
)


@pytest.mark.parametrize("name", sorted(SUITES))
def test_suite_notes_do_not_assert_a_ranking(name: str) -> None:
    suite = SUITES[name]
    for text in (suite.note, suite.setup_note, *(g.note for g in suite.groups)):
        found = _RANKING_WORDS.findall(text)
        assert not found, f"{name}: {found}"


# --- every generated sentence agrees with the rows -------------------------------------

_ITEM = re.compile(
    r"(?P<method>[\w-]+) (?P<mean>n/a|[-+.\w]+)(?: ± (?P<std>[-+.\w]+))?"
    r"(?: \((?P<k>\d+) of (?P<n>\d+) runs\))?$"
)
_LOWER = {"rmse_m": True, "coverage_pct": False}


def _oracle(a: Row, b: Row) -> str:
    """How ``a`` compares with ``b``, from the rule table.md states."""
    if not (math.isfinite(a.mean) and math.isfinite(b.mean)):
        return "missing"
    if a.mean == b.mean:
        return "level"
    lower = _LOWER[a.metric]
    a_first = a.mean < b.mean if lower else a.mean > b.mean
    if a.finite < 2 or b.finite < 2:
        return "a-unjudged" if a_first else "b-unjudged"
    se = math.sqrt(a.std**2 / a.finite + b.std**2 / b.finite)
    if abs(a.mean - b.mean) <= se:
        return "level"
    return "a" if a_first else "b"


def _shown(value: float) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.4g}"


def _check_ranking_line(line: str, rows: dict[tuple[str, str, str], Row]) -> None:
    head, body = line.split(": ", 1)
    scenario, rest = head.split(", ", 1)
    metric = rest.split(" ", 1)[0]
    chain, _, missing = ("; " + body).partition("; no number: ")
    chain = chain.removeprefix("; ")
    group = {m: r for (s, mt, m), r in rows.items() if s == scenario and mt == metric}
    for m in filter(None, missing.split(", ")):
        assert not math.isfinite(group[m].mean)
    if not chain or chain.startswith("only "):
        return
    tokens = re.split(r", (ahead of|level with|then) ", chain)
    items, connectors = tokens[0::2], tokens[1::2]
    methods = []
    for text in items:
        match = _ITEM.match(text)
        assert match, text
        r = group[match["method"]]
        assert match["mean"] == _shown(r.mean)
        methods.append(r.method)
    assert sorted(methods) == sorted(m for m, r in group.items() if math.isfinite(r.mean))
    for upper, lower, word in zip(methods[:-1], methods[1:], connectors, strict=True):
        verdict = _oracle(group[upper], group[lower])
        expected = {"a": "ahead of", "level": "level with", "a-unjudged": "then"}
        assert expected.get(verdict) == word, (line, upper, lower, verdict)


def _check_pair_line(
    line: str, rows: dict[tuple[str, str, str], Row], scenarios: list[str]
) -> None:
    if ", in all " in line:
        head, claims = line.split(": ", 1)
        metric = head.split(" ", 1)[0]
        for claim in claims.split("; "):
            a, b = claim.split(" ahead of ")
            for s in scenarios:
                assert _oracle(rows[s, metric, a], rows[s, metric, b]) == "a", (line, s)
        return
    head, body = line.split(": ", 1)
    metric, pair = head.split(", ", 1)
    a, b = pair.split(" vs ")
    seen = []
    for part in body.split("; "):
        phrase, where = part.split(" in ", 1)
        for s, x, y in re.findall(r"([^,(]+?) \((\S+) vs (\S+)\)", where):
            s = s.strip()
            ra, rb = rows[s, metric, a], rows[s, metric, b]
            assert (x, y) == (_shown(ra.mean), _shown(rb.mean))
            verdict = _oracle(ra, rb)
            word = "lower" if _LOWER[metric] else "higher"
            expected = {
                "a": f"{a} ahead",
                "b": f"{b} ahead",
                "level": "level",
                "a-unjudged": f"{a} {word}, unjudged,",
                "b-unjudged": f"{b} {word}, unjudged,",
                "missing": "no number",
            }[verdict]
            assert phrase == expected, (line, s)
            seen.append(s)
    assert sorted(seen) == sorted(scenarios)


def _check_difference_line(line: str, rows: dict[tuple[str, str, str], Row]) -> None:
    head = line.split(": ", 1)[0]
    scenario, rest = head.split(", ", 1)
    metric = rest.split(" ", 1)[0]
    lower = _LOWER[metric]
    swaps = line.split("Swapped against the seed: ", 1)[1].split("; ")
    assert swaps
    for swap in swaps:
        match = re.match(r"([\w-]+) \S+ (ahead of|level with|before) ([\w-]+) \S+", swap)
        assert match, swap
        first, word, second = match.groups()
        rf, rs = rows[scenario, metric, first], rows[scenario, metric, second]
        ours_first = rf.mean < rs.mean if lower else rf.mean > rs.mean
        seed_second = rs.paper < rf.paper if lower else rs.paper > rf.paper
        assert ours_first, swap
        assert seed_second, swap
        expected = {"a": "ahead of", "level": "level with", "a-unjudged": "before"}
        assert expected[_oracle(rf, rs)] == word, swap


@st.composite
def _tables(draw: st.DrawFn) -> list[Row]:
    n_scen = draw(st.integers(1, 3))
    methods = ["m-a", "m-b", "m-c", "m-d"][: draw(st.integers(2, 4))]
    metrics = draw(st.sampled_from([["rmse_m"], ["coverage_pct"], ["rmse_m", "coverage_pct"]]))
    runs = draw(st.integers(1, 4))
    rows = []
    for s in [f"case {i}" for i in range(n_scen)]:
        for m in methods:
            for metric in metrics:
                finite = draw(st.integers(0, runs))
                mean = draw(st.integers(1, 60)) / 20 if finite else NAN
                std = draw(st.integers(0, 20)) / 20 if finite > 1 else NAN
                paper = draw(st.one_of(st.just(NAN), st.integers(1, 60).map(lambda k: k / 20)))
                rows.append(Row(s, m, metric, mean, std, paper, runs, finite))
    return rows


@settings(max_examples=300)
@given(_tables())
def test_every_sentence_agrees_with_the_rows(rows: list[Row]) -> None:
    by_key = {(r.scenario, r.metric, r.method): r for r in rows}
    scenarios = list(dict.fromkeys(r.scenario for r in rows))
    runs = rows[0].runs
    md = table_markdown(INDOOR, rows, runs=runs, duration=None, methods=INDOOR.methods)
    section = ""
    checked = 0
    for line in md.splitlines():
        if line.startswith("## "):
            section = line
        elif line.startswith("- ") and section == "## Rankings":
            _check_ranking_line(line[2:], by_key)
            checked += 1
        elif line.startswith("- ") and section.startswith("## Pairs"):
            _check_pair_line(line[2:], by_key, scenarios)
            checked += 1
        elif line.startswith("- ") and section.startswith("## Where our ranking"):
            _check_difference_line(line[2:], by_key)
            checked += 1
    # Every (scenario, metric) gets its ranking line.
    assert checked >= len({(r.scenario, r.metric) for r in rows})


def test_the_table_says_how_to_rerun_a_row_where_compare_writes_it(tmp_path: Path) -> None:
    """table.md names the run folder and the command that reruns a run; the folder is
    where write_run_files puts each run (its seed is its run)."""
    md = table_markdown(INDOOR, [], runs=1, duration=None, methods=INDOOR.methods)
    assert "`runs/<case>/<method>/seed-<n>/`" in md
    assert "`dronetrack simulate --config runs/<case>/<method>/seed-<n>/config.toml`" in md
    done = RunMetrics("fast", "pf-delta", 3, {})
    assert run_dir(tmp_path, done) == tmp_path / "runs" / "fast" / "pf-delta" / "seed-3"
