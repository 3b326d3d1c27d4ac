"""results.jsonl: appends, resumes, and survives a torn last line."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from dronetrack.experiments.sweep.store import ResultStore, read_results


def test_resume_and_no_duplicates(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    store = ResultStore(path)
    assert store.add({"key": "a", "metrics": {"x": np.float64(1.5), "n": np.int64(3)}})
    assert store.add({"key": "b", "metrics": {"x": math.nan}})
    assert not store.add({"key": "a", "metrics": {}})  # already done
    again = ResultStore(path)
    assert again.done == {"a", "b"}
    rows = list(read_results(path))
    assert [r["key"] for r in rows] == ["a", "b"]
    assert rows[0]["metrics"] == {"x": 1.5, "n": 3}
    assert rows[1]["metrics"] == {"x": None}  # strict JSON: no NaN


def test_a_torn_last_line_is_skipped_and_the_next_starts_fresh(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "results.jsonl"
    path.write_text(json.dumps({"key": "a"}) + "\n" + '{"key": "b", "metr')
    with caplog.at_level(logging.WARNING):
        store = ResultStore(path)
    assert store.done == {"a"}
    assert "line 2 is not complete JSON" in caplog.text
    assert store.add({"key": "b"})
    assert [r["key"] for r in read_results(path)] == ["a", "b"]
    assert path.read_text().splitlines()[-1] == '{"key": "b"}'
