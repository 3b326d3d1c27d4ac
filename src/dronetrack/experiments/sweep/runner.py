"""Running a sweep: every run on an executor, each result stored as soon as it arrives.

Executors are anything with the standard ``concurrent.futures`` interface:
- by default a local ``ProcessPoolExecutor`` (forkserver processes, no server).
  When a worker process dies the pool breaks; the results already stored stay,
  and the unfinished runs go to a new pool.  A run that was executing when a pool
  broke, three times, is recorded as failed, so one run that always kills its
  worker cannot stall the sweep;
- with ``--scheduler tcp://HOST:PORT``, an existing Dask distributed cluster
  (extra ``dask``), whose nannies restart dead workers and reschedule their runs.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing as mp
import os
import signal
import socket
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any, cast

from dronetrack.errors import ConfigError, DronetrackError, MissingExtraError
from dronetrack.experiments.sweep.grid import RunSpec, run_config
from dronetrack.experiments.sweep.store import ResultStore
from dronetrack.interrupt import stop_requested, stoppable

__all__ = ["MAX_ATTEMPTS", "dask_executor", "local_executor", "run_one", "run_sweep"]

log = logging.getLogger(__name__)

MAX_ATTEMPTS = 3
SIGMA_KEYS = ("sigma_pos", "sigma_vel", "sigma_acc", "sigma_m")
Progress = Callable[[int, int, dict[str, Any]], None]
ExecutorFactory = Callable[[], cf.Executor]


def run_one(run: RunSpec) -> dict[str, Any]:
    """One run of a sweep, a closed-loop simulation or a replay, as its result line."""
    start = time.perf_counter()
    row: dict[str, Any] = {
        "key": run.key,
        "params": run.params,
        "seed": run.seed,
        "source": run.source,
        "duration": run.duration,
        "host": socket.gethostname(),
        "pid": os.getpid(),
    }
    try:
        metrics, resolved = _execute(run)
    except DronetrackError as err:
        row["error"] = str(err)
        return row
    tracker = resolved.pipeline.tracker
    row["tracker"] = tracker.kind
    row["sigma"] = {k: getattr(tracker, k) for k in SIGMA_KEYS}
    row["eq11"] = _eq11(resolved)
    row["metrics"] = metrics
    row["wall_s"] = time.perf_counter() - start
    return row


def _execute(run: RunSpec) -> tuple[dict[str, Any], Any]:
    if "recording" in run.source:
        from dronetrack.jobs.replay import recording_config, run_replay
        from dronetrack.sources.recordings.opener import open_recording

        rec = open_recording(Path(run.source["recording"]))
        replay = run_replay(rec, run_config(recording_config(rec, None), run))
        return replay.metrics(), replay.run.config
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    sim = run_simulation(run_config(get_scenario(run.source["scenario"]), run))
    return sim.metrics(), sim.config


def _eq11(cfg: Any) -> dict[str, float]:
    """Seed 000's analytic σ values (eq. 11) for the run's drone and frame period."""
    from dronetrack.pipeline.trackers import DEFAULT_S_DIAG
    from dronetrack.track.particle import eq11_parameters

    t = cfg.pipeline.tracker
    s_diag = DEFAULT_S_DIAG if t.s_diag is None else t.s_diag
    p = eq11_parameters(t.v_max, t.a_max, s_diag, cfg.sensor.integration_time_s)
    return {
        "sigma_pos": p.sigma_pos,
        "sigma_vel": p.sigma_vel,
        "sigma_acc": p.sigma_acc,
        "sigma_m": p.sigma_m,
    }


def _ignore_sigint() -> None:
    """Worker start-up: Ctrl-C is the parent's to handle (it stops the pool)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def local_executor(workers: int) -> ExecutorFactory:
    """Local worker processes (forkserver: safe with numba's and rich's threads).

    The workers ignore Ctrl-C, which a terminal sends to every process of the group:
    the sweep decides what an interrupt means (``run_sweep``), not each run.
    """
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    context = mp.get_context("forkserver")
    return lambda: cf.ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=_ignore_sigint
    )


def dask_executor(address: str) -> tuple[ExecutorFactory, Callable[[], None]]:
    """An executor on the Dask cluster at ``address``, and the function that disconnects."""
    try:
        import distributed
    except ImportError:
        raise MissingExtraError(
            "--scheduler needs dask.distributed: pip install 'dronetrack[dask]'"
        ) from None
    try:
        client: Any = cast(Any, distributed).Client(address, timeout="5s")
    except (OSError, TimeoutError, ValueError) as err:
        raise ConfigError(f"cannot reach the Dask scheduler at {address}: {err}") from None
    return (lambda: client.get_executor(pure=False)), client.close


@contextmanager
def sweep_executor(workers: int | None, scheduler: str | None) -> Iterator[ExecutorFactory]:
    """The executors a sweep runs on: the Dask cluster at ``scheduler`` (disconnected
    after the block), else ``workers`` local processes (default: one per core)."""
    if scheduler is not None and workers is not None:
        raise ConfigError("give --workers or --scheduler, not both")
    if scheduler is None:
        yield local_executor(workers or os.cpu_count() or 1)
        return
    make, close = dask_executor(scheduler)
    try:
        yield make
    finally:
        close()


def run_sweep(
    runs: Sequence[RunSpec],
    store: ResultStore,
    executor: ExecutorFactory,
    progress: Progress | None = None,
) -> Counter[str]:
    """Run every run not yet in ``store``; return counts of "done", "failed", "skipped",
    and "unfinished" when Ctrl-C stopped the sweep.

    Results are stored as they arrive, so an interruption or a dead worker loses none
    of the finished ones; rerunning the sweep only runs what is missing.  A Ctrl-C
    handled by ``dronetrack.interrupt`` stops the workers at once: the runs they
    had in hand are not stored (not even as failed), so a rerun does them.
    """
    counts: Counter[str] = Counter(skipped=sum(1 for r in runs if r.key in store.done))
    suspects: Counter[str] = Counter()  # pool breaks while a run was executing
    total = len(runs)
    pending = [r for r in runs if r.key not in store.done]
    if progress is not None:
        progress(counts["skipped"], total, {})
    while pending:
        with stoppable():
            broken = _one_pool(pending, store, executor, counts, suspects, progress, total)
        pending = [r for r in pending if r.key not in store.done]
        if stop_requested():
            counts["unfinished"] = len(pending)
            break
        if not broken:
            break
        for run in pending:
            if suspects[run.key] >= MAX_ATTEMPTS:
                row = {"key": run.key, "params": run.params, "seed": run.seed}
                row["error"] = f"the worker died {MAX_ATTEMPTS} times running it"
                _store(store, row, counts, progress, total)
        pending = [r for r in pending if r.key not in store.done]
        if pending:
            log.warning("a worker died; %d runs go to a new pool", len(pending))
    return counts


def _one_pool(
    pending: Sequence[RunSpec],
    store: ResultStore,
    make: ExecutorFactory,
    counts: Counter[str],
    suspects: Counter[str],
    progress: Progress | None,
    total: int,
) -> bool:
    """Submit ``pending`` to one executor; True if its pool broke.

    The runs a worker has taken are noted at every completion and every second, so
    when the pool breaks, those are the suspects (the one that killed its worker is
    among them; the others only lose an attempt of the three).
    """
    ex = make()
    futures: dict[cf.Future[dict[str, Any]], RunSpec] = {}
    try:
        futures = {ex.submit(run_one, run): run for run in pending}
        waiting: set[cf.Future[dict[str, Any]]] = set(futures)
        started: set[cf.Future[dict[str, Any]]] = set()
        while waiting and not stop_requested():
            done, waiting = cf.wait(waiting, timeout=1.0, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                run = futures[fut]
                try:
                    row = fut.result()
                except BrokenProcessPool:
                    for f in started | {fut}:
                        suspects[futures[f].key] += 1
                    return True
                except Exception as exc:  # a run the cluster gave up on (e.g. KilledWorker)
                    row = {"key": run.key, "params": run.params, "seed": run.seed}
                    row["error"] = repr(exc)
                _store(store, row, counts, progress, total)
            started = {f for f in waiting if f.running()}
        return False
    finally:
        for f in futures:  # the runs not yet started (a broken pool's, or on an interrupt)
            f.cancel()
        if stop_requested() or sys.exc_info()[0] is not None:
            _terminate_workers(ex)  # runs in hand are dropped, to be run again on resume
        ex.shutdown(wait=False)


def _terminate_workers(ex: cf.Executor) -> None:
    """Stop a local pool's worker processes now (their runs are lost, none is stored)."""
    terminate = getattr(ex, "terminate_workers", None)  # Python 3.14 and later
    if callable(terminate):
        terminate()
        return
    processes = getattr(ex, "_processes", None) or {}
    for process in list(processes.values()):
        process.terminate()


def _store(
    store: ResultStore,
    row: dict[str, Any],
    counts: Counter[str],
    progress: Progress | None,
    total: int,
) -> None:
    if store.add(row):
        counts["failed" if "error" in row else "done"] += 1
    if progress is not None:
        progress(counts["skipped"] + counts["done"] + counts["failed"], total, row)
