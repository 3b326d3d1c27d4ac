"""The sweep loop against a stand-in pool: a run that always kills its worker."""

from __future__ import annotations

import concurrent.futures as cf
import threading
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from dronetrack.experiments.sweep.grid import RunSpec
from dronetrack.experiments.sweep.runner import MAX_ATTEMPTS, run_sweep
from dronetrack.experiments.sweep.store import ResultStore, read_results


class DyingPool(cf.Executor):
    """Finishes every run at once, except the ``bad`` one, whose worker dies: the pool
    then breaks, failing that run's future with BrokenProcessPool."""

    pools = 0

    def __init__(self) -> None:
        DyingPool.pools += 1

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future[Any]:
        run: RunSpec = args[0]
        future: cf.Future[Any] = cf.Future()
        future.set_running_or_notify_cancel()
        if run.params["bad"]:
            threading.Timer(0.05, future.set_exception, [BrokenProcessPool("died")]).start()
        else:
            future.set_result({"key": run.key, "params": run.params, "metrics": {"frames": 1}})
        return future


def test_a_run_that_always_kills_its_worker_fails_after_three_pools(tmp_path: Path) -> None:
    runs = [RunSpec({"scenario": "x"}, None, {"bad": k == 2, "k": k}, 0) for k in range(5)]
    store = ResultStore(tmp_path / "results.jsonl")
    DyingPool.pools = 0
    counts = run_sweep(runs, store, DyingPool)
    assert counts == {"done": 4, "failed": 1, "skipped": 0}
    assert DyingPool.pools == MAX_ATTEMPTS
    rows = {r["params"]["k"]: r for r in read_results(tmp_path / "results.jsonl")}
    assert sorted(rows) == [0, 1, 2, 3, 4]
    assert rows[2]["error"] == f"the worker died {MAX_ATTEMPTS} times running it"
    assert all("error" not in rows[k] for k in (0, 1, 3, 4))
