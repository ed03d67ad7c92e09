"""One sweep trial in a worker process, and the executors that run trials.

Split from :mod:`hapticframe.sweep._sweep` (which plans the points and aggregates the rows):
:func:`run_trial` runs one seeded ``run_experiment`` with figures and the recording off and
measures its cost (wall and CPU time, steps, peak memory) under a time limit;
:func:`make_executor` builds the local process pool (fork-server workers tied to the
sweep's process) or a Dask client's executor; :func:`_gather` runs the tasks and turns a
lost or hung task into a row.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticframe._config._load import LoadedFile
from hapticframe._config._overrides import (
    Override,
    validate_with_overrides,
)
from hapticframe._errors import HapticframeError, UsageError

__all__ = ["COST_KEYS", "EXECUTORS", "SEARCH_KEYS", "TrialTask", "make_executor", "run_trial"]


#: The executors :func:`make_executor` builds.
EXECUTORS = ("process", "dask")
#: Seconds a trial may overrun ``timeout_s`` before the sweep stops waiting for it (its
#: worker's own alarm normally ends it first; this catches a hang in compiled code).
_GRACE_S = 10.0


SEARCH_KEYS = ("object_found", "centroid_error_m", "hausdorff_est_to_true_m",
               "hausdorff_true_to_est_m", "movements", "ems_phase1", "ems_phase2",
               "object_interactions", "max_force_n")
COST_KEYS = ("wall_time_s", "cpu_time_s", "wall_time_per_step_s", "cpu_time_per_step_s",
             "peak_rss_bytes")


def _init_worker(owner_pid: int, task: TrialTask | None) -> None:
    """A process pool worker's initializer.

    The worker ends itself once the sweep's process ``owner_pid`` has ended, however it
    ended (see :mod:`hapticframe.sweep._lifeline`: its parent is the fork server, which
    outlives a killed sweep as long as a worker does; a killed sweep that is not reaped yet
    is a zombie whose id still exists), and Linux kills it with its parent. Then one
    untimed run of ``task`` into a folder of this process's own, removed after, so that the
    worker's first trial (the baseline's, always) pays no import or first-call costs. Never
    raises (a failing run is a row).
    """
    import shutil

    from hapticframe.sweep._lifeline import die_with_parent, watch_process

    die_with_parent()
    watch_process(owner_pid)
    if task is None:
        return
    out = f"{task.out_dir}-{os.getpid()}"
    run_trial(dataclasses.replace(task, out_dir=out))
    shutil.rmtree(out, ignore_errors=True)


# --- one trial, in a worker ------------------------------------------------------------------


@dataclass(frozen=True)
class TrialTask:
    """Everything a worker needs to run one trial (picklable)."""

    point: int
    trial: int
    seed: int
    loaded: LoadedFile
    overrides: tuple[Override, ...]
    out_dir: str
    timeout_s: float | None = None
    plugin_modules: tuple[str, ...] = ()
    plugin_dir: str | None = None


class _TrialTimeout(BaseException):
    """Raised in a worker's main thread when a trial runs past its time limit.

    A BaseException, as KeyboardInterrupt is: the alarm can land inside code that catches
    ``Exception`` to stay best-effort (provenance, hooks, clean-up), which must not swallow it.
    """


def _reset_peak_rss() -> bool:
    """Reset this process's peak resident memory (Linux: ``/proc/self/clear_refs``)."""
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        return True
    except OSError:
        return False


def _peak_rss_bytes(reset: bool) -> int | None:
    """The peak resident memory since the reset (else since the process started)."""
    if reset:
        try:
            with open("/proc/self/status") as handle:
                for line in handle:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1]) * 1024
        except (OSError, ValueError, IndexError):
            pass
    try:
        import resource
    except ImportError:  # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak if sys.platform == "darwin" else peak * 1024)


def _cpu_time_s() -> float:
    times = os.times()  # user + system of every thread of this process
    return float(times.user + times.system)


def _steps(out_dir: Path) -> int | None:
    """Robot steps of a finished run (from ``trace.npz``); sensor reads of an open loop."""
    try:
        import numpy as np

        with np.load(out_dir / "trace.npz") as trace:
            robots = [len(trace[k]) for k in trace.files
                      if k.startswith("robot/") and k.endswith("/timestamps_s")]
            if robots:
                return int(sum(robots))
            sensors = [len(trace[k]) for k in trace.files
                       if k.startswith("sensor/") and k.endswith("/timestamps_s")]
            return int(max(sensors)) if sensors else None
    except (OSError, ValueError, KeyError):
        return None


def _scalars(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """The scalar metrics of a run (numbers, booleans, None); NaN kept as NaN."""
    out: dict[str, Any] = {}
    for key, value in metrics.items():
        if isinstance(value, bool) or value is None:
            out[key] = value
        elif isinstance(value, (int, float)):
            out[key] = float(value) if isinstance(value, float) else int(value)
        elif hasattr(value, "item") and getattr(value, "shape", None) == ():
            out[key] = value.item()
    return out


@contextlib.contextmanager
def _alarm(timeout_s: float | None) -> Iterator[dict[str, bool]]:
    """Raise :class:`_TrialTimeout` after ``timeout_s`` while ``state["armed"]`` (main thread
    with SIGALRM only: elsewhere the sweep's own wait is the limit); ``state["fired"]``
    says it did."""
    state = {"armed": True, "fired": False}
    usable = (timeout_s is not None and hasattr(signal, "setitimer")
              and threading.current_thread() is threading.main_thread())
    if not usable:
        yield state
        return

    def handler(signum: int, frame: Any) -> None:
        if state["armed"]:  # not once the trial is over: its row is already written
            state["fired"] = True
            raise _TrialTimeout(f"past the time limit of {timeout_s:g} s")

    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, float(timeout_s or 0))
    try:
        yield state
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run_trial(task: TrialTask) -> dict[str, Any]:
    """Run one trial and measure it; never raises for a failing run (the row says why)."""
    from hapticframe.record._recorded import run_experiment

    out = Path(task.out_dir)
    row: dict[str, Any] = {"point": task.point, "trial": task.trial, "seed": task.seed,
                           "status": "ok", "error": None, "metrics": {},
                           "run_dir": str(out)}
    reset = _reset_peak_rss()
    wall0, cpu0 = time.perf_counter(), _cpu_time_s()
    # A run's warnings (a lasso capped at 10 sweeps warns every frame) are counted in its
    # row, not printed by every worker over the sweep's progress.
    with _alarm(task.timeout_s) as alarm, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            experiment = validate_with_overrides(
                task.loaded, task.overrides, plugin_modules=task.plugin_modules,
                plugin_dir=task.plugin_dir)
            summary = run_experiment(experiment, out, overwrite=True, echo=lambda _t: None,
                                     progress=False)
            row["metrics"] = _scalars(summary)
        except (Exception, _TrialTimeout) as exc:  # a failing point is a row, not a crash
            if not alarm["fired"]:
                row["status"] = "failed"
                row["error"] = (str(exc) if isinstance(exc, HapticframeError)
                                else f"{type(exc).__name__}: {exc}")
        finally:
            alarm["armed"] = False
    if alarm["fired"]:  # however the run ended after the alarm, it ran past the limit
        row["status"], row["error"] = "timeout", f"past --timeout-s {task.timeout_s:g}"
        row["metrics"] = {}
    messages = list(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))
    row["warnings"] = {"count": len(caught), "messages": messages[:3]}
    row["wall_time_s"] = time.perf_counter() - wall0
    row["cpu_time_s"] = _cpu_time_s() - cpu0
    row["peak_rss_bytes"] = _peak_rss_bytes(reset)
    steps = _steps(out) if row["status"] == "ok" else None
    row["steps"] = steps
    row["wall_time_per_step_s"] = row["wall_time_s"] / steps if steps else None
    row["cpu_time_per_step_s"] = row["cpu_time_s"] / steps if steps else None
    row["non_finite"] = sorted(k for k, v in row["metrics"].items()
                               if isinstance(v, float) and not math.isfinite(v))
    _mark_nan(row, [k for k in row["non_finite"] if _is_accuracy_key(k)])
    return row


def _mark_nan(row: dict[str, Any], keys: Sequence[str]) -> None:
    """Make a finished row a ``nan`` row for its non-finite ``keys``."""
    if row["status"] == "ok" and keys:
        row["status"], row["error"] = "nan", f"non-finite metrics: {', '.join(sorted(keys))}"


def _mark_nan_against_baseline(rows: Sequence[dict[str, Any]]) -> None:
    """A non-finite metric that is not an accuracy (``max_measured_force_n``, say) fails a
    trial only where the baseline reports it finite: a perception run has no force sensor,
    so that metric is NaN in every run, the file's own included, and means nothing."""
    finite = {k for r in rows if r["point"] == 0 and r["status"] == "ok"
              for k, v in r["metrics"].items() if k not in r.get("non_finite", ())
              and isinstance(v, (int, float))}
    for row in rows:
        _mark_nan(row, [k for k in row.get("non_finite", ()) if k in finite])


# --- executors -------------------------------------------------------------------------------


@contextlib.contextmanager
def make_executor(kind: str = "process", workers: int | None = None,
                  scheduler: str | None = None,
                  warm_up: TrialTask | None = None) -> Iterator[Executor]:
    """The executor trials run on, shut down when the block ends.

    Parameters
    ----------
    kind : {"process", "dask"}
        ``process``: a local process pool, its workers started by a fork server where the
        platform has one (Linux, macOS), else spawned. ``dask``: a ``dask.distributed``
        client's executor, on the cluster at ``scheduler`` (``tcp://HOST:8786``) or,
        without one, on a ``LocalCluster`` of ``workers`` single-threaded processes; a task
        lost with its worker is retried twice.
    workers : int, optional
        Processes of the local pool or cluster (default: one per CPU).
    scheduler : str, optional
        The Dask scheduler's address (``dask`` only).
    warm_up : TrialTask, optional
        ``process`` only: a trial each worker runs once, untimed, when it starts.
    """
    n = max(1, int(workers or os.cpu_count() or 1))
    if kind == "process":
        if scheduler is not None:
            raise UsageError("--scheduler is for --executor dask")
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # Not "fork": a child forked from a process that has run torch (OpenMP) or other
        # thread pools can block for ever on a lock one of those threads held.
        methods = multiprocessing.get_all_start_methods()
        context = multiprocessing.get_context("forkserver" if "forkserver" in methods
                                              else "spawn")
        pool = ProcessPoolExecutor(max_workers=n, mp_context=context,
                                   initializer=_init_worker, initargs=(os.getpid(), warm_up))
        try:
            yield pool
        finally:
            _shutdown_pool(pool)
        return
    if kind == "dask":
        try:
            from dask.distributed import (  # type: ignore[import-not-found, unused-ignore]
                Client,
                LocalCluster,
            )
        except ImportError:
            raise UsageError("--executor dask needs dask.distributed: "
                             "pip install 'hapticframe[distributed]'") from None
        with contextlib.ExitStack() as stack:
            if scheduler is None:
                cluster = stack.enter_context(LocalCluster(  # type: ignore[no-untyped-call, unused-ignore]
                    n_workers=n, threads_per_worker=1, processes=True,
                    dashboard_address=None))
                client = stack.enter_context(Client(cluster))  # type: ignore[no-untyped-call, unused-ignore]
            else:
                client = stack.enter_context(Client(scheduler))  # type: ignore[no-untyped-call, unused-ignore]
            yield client.get_executor(pure=False, retries=2)
        return
    raise UsageError(f"unknown executor {kind!r}; choose one of {', '.join(EXECUTORS)}")


def _shutdown_pool(pool: Any, patience_s: float = 5.0) -> None:
    """Shut a process pool down without waiting for ever on a trial that hangs past its
    limit: a worker still busy ``patience_s`` after the shutdown is terminated."""
    processes = list((getattr(pool, "_processes", None) or {}).values())  # private, guarded
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + patience_s
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.terminate()
    pool.shutdown(wait=True)


def _gather(executor: Executor, tasks: Sequence[TrialTask], workers: int,
            timeout_s: float | None,
            on_row: Callable[[dict[str, Any], int], None],
            warmed: bool = False) -> list[dict[str, Any]]:
    """Run ``tasks`` on ``executor``; a trial that outlives its limit (and the grace the
    worker's own alarm has) is a ``timeout`` row. Rows come back in task order. ``warmed``:
    each worker runs a warm-up trial (bounded by ``timeout_s`` too) before its first task,
    whose limit is extended by as much."""
    futures: dict[Future[dict[str, Any]], int] = {
        executor.submit(run_trial, task): i for i, task in enumerate(tasks)}
    rows: list[dict[str, Any] | None] = [None] * len(tasks)
    pending = set(futures)
    order = sorted(futures, key=futures.__getitem__)
    started: dict[Future[dict[str, Any]], float] = {}
    while pending:
        now = time.monotonic()
        # The first `workers` unfinished tasks in submission order are the ones running.
        for future in [f for f in order if f in pending][:workers]:
            started.setdefault(future, now)
        done, pending = wait(pending, timeout=1.0, return_when=FIRST_COMPLETED)
        for future in done:
            index = futures[future]
            try:
                row = future.result()
            except Exception as exc:  # the worker itself died (killed, out of memory)
                row = _lost_row(tasks[index], f"the worker failed: {type(exc).__name__}: {exc}")
            rows[index] = row
            on_row(row, len(pending))
        if timeout_s is None:
            continue
        limit = timeout_s + max(_GRACE_S, 0.5 * timeout_s)
        first = set(order[:workers]) if warmed else set()
        for future in [f for f in pending if time.monotonic() - started.get(f, now)
                       > limit + (timeout_s if f in first else 0.0)]:
            future.cancel()
            pending.discard(future)
            index = futures[future]
            rows[index] = _lost_row(tasks[index], f"past --timeout-s {timeout_s:g} (no answer "
                                    "from its worker)", status="timeout")
            on_row(rows[index] or {}, len(pending))
    return [row for row in rows if row is not None]


def _lost_row(task: TrialTask, error: str, status: str = "failed") -> dict[str, Any]:
    return {"point": task.point, "trial": task.trial, "seed": task.seed, "status": status,
            "error": error, "metrics": {}, "run_dir": task.out_dir, "wall_time_s": None,
            "cpu_time_s": None, "peak_rss_bytes": None, "steps": None,
            "wall_time_per_step_s": None, "cpu_time_per_step_s": None}


def _is_onset_key(key: str) -> bool:
    return "onset" in key or (key.startswith(("first_", "last_")) and key.endswith("_error_s"))


def _is_accuracy_key(key: str) -> bool:
    """Whether a metric is one of the accuracies the tables show (a NaN there is a
    numerical failure of the trial; elsewhere, see :func:`_mark_nan_against_baseline`)."""
    return (key in SEARCH_KEYS or key.endswith("_balanced_accuracy") or _is_onset_key(key)
            or "auc" in key or "log_loss" in key)
