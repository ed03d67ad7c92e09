"""The search suite's workers die with it, and a re-run resumes what an interrupted run finished.

Issue 16 §4. The runs are faked (as in test_bench_search.py): what is under test is the
pool, the kept trials and the summary, not the search. The kill test runs the suite in a
subprocess with two workers, kills it with SIGKILL while one trial is finished and the
other is still running, and checks that no worker outlives it and that a re-run keeps the
finished trial, runs the other again from scratch and writes an uninterrupted run's summary.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hapticframe import BenchOptions, RunError
from hapticframe_bench import _search
from hapticframe_bench._search import TRIAL_FILE, run_suite

#: Only the two-phase planner, on one trial per shape: two runs.
TWO_RUNS: dict[str, Any] = {"shapes": ("circle", "ellipse"),
                            "planners": {"search": "two-phase-coverage"}}
#: Bounds of the waits on the subprocess: generous, for a loaded machine; never a timing assert.
START_WAIT_S = 120.0
DEATH_WAIT_S = 30.0


@pytest.fixture(autouse=True)
def _no_figure(monkeypatch: pytest.MonkeyPatch) -> None:
    """search.png is not under test here, and drawing it costs seconds on a loaded machine."""
    monkeypatch.setattr(_search, "save_trial_figure", lambda path, summary: True)


def _metrics(error: float) -> dict[str, Any]:
    return {"object_found": True, "centroid_error_m": error, "hausdorff_est_to_true_m": 0.01,
            "hausdorff_true_to_est_m": 0.02, "movements": 6, "ems_phase1": 2, "ems_phase2": 4,
            "object_interactions": 3, "max_force_n": 40.0, "wall_time_s": 1.0}


def _fake_run(calls: list[str], fail: str = "") -> Callable[..., dict[str, Any]]:
    """A run_experiment that writes a file, records its call and fails for ``fail``."""

    def fake_run(experiment: Any, out_dir: Path, *, overwrite: bool,
                 echo: Any) -> dict[str, Any]:
        out = Path(out_dir)
        # Every run starts from an empty directory: nothing of an earlier attempt is left.
        assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())
        out.mkdir(parents=True)
        (out / "metrics.json").write_text("{}", encoding="utf-8")
        calls.append(out.name)
        if out.name == fail:
            raise RunError("the run failed: simulated breakdown")
        return _metrics(0.01 if experiment.model.planners[0].type == "coverage" else 0.02)

    return fake_run


def _stable(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without what differs between two runs of the same trials (times, where)."""
    out = {k: v for k, v in summary.items() if k not in ("wall_time_s", "command", "kept_runs")}
    out["runs"] = [{k: v for k, v in r.items() if k != "wall_time_s"} for r in summary["runs"]]
    return out


def _suite(out: Path, lines: list[str] | None = None, seed: int = 0,
           **kwargs: Any) -> dict[str, Any]:
    options = BenchOptions(out_dir=out, trials=kwargs.pop("trials", 1), seed=seed, workers=1,
                           echo=(lines if lines is not None else []).append)
    # The planner and the baseline: what resuming keeps is the same for any set of roles.
    kwargs.setdefault("planners", {"search": "two-phase-coverage", "baseline": "coverage"})
    return run_suite(options, **kwargs)


# --- resuming, in this process -------------------------------------------------------------


def test_a_rerun_keeps_every_finished_trial_and_writes_the_same_summary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[str] = []
    monkeypatch.setattr(_search, "run_experiment", _fake_run(calls))
    first = _suite(tmp_path)
    assert len(calls) == 4 and first["kept_runs"] == 0
    for name in calls:
        kept = json.loads((tmp_path / "trials" / name / TRIAL_FILE).read_text("utf-8"))
        assert len(kept["fingerprint"]) == 64 and kept["record"]["status"] == "ok"
    assert not list(tmp_path.rglob("*.part"))

    calls.clear()
    lines: list[str] = []
    again = _suite(tmp_path, lines)
    assert calls == []
    assert again["kept_runs"] == 4
    assert lines[1] == f"resuming: 4 of 4 runs kept from {tmp_path / 'trials'}"
    progress = [ln for ln in lines if ln.startswith("[")]
    assert len(progress) == 4 and all("kept from an earlier run" in ln for ln in progress)
    assert _stable(again) == _stable(first)
    assert _stable(json.loads((tmp_path / "search.json").read_text("utf-8"))) == _stable(first)


def test_an_unfinished_corrupt_or_stale_trial_runs_again_from_scratch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[str] = []
    monkeypatch.setattr(_search, "run_experiment", _fake_run(calls))
    first = _suite(tmp_path)
    trials = tmp_path / "trials"
    # Killed before its record was written: a complete-looking run without the file.
    unfinished = trials / "circle-0-coverage"
    (unfinished / TRIAL_FILE).unlink()
    (unfinished / "stale.png").write_bytes(b"left by the killed run")
    (unfinished / (TRIAL_FILE + ".part")).write_text('{"fingerprint": ', "utf-8")
    # A record cut short, and one from other settings or code.
    corrupt = trials / "ellipse-0-coverage" / TRIAL_FILE
    corrupt.write_text(corrupt.read_text("utf-8")[:40], "utf-8")
    stale = trials / "ellipse-0-two-phase-coverage" / TRIAL_FILE
    stale.write_text(stale.read_text("utf-8").replace('"fingerprint": "', '"fingerprint": "0'),
                     "utf-8")

    calls.clear()
    lines: list[str] = []
    again = _suite(tmp_path, lines)
    assert sorted(calls) == ["circle-0-coverage", "ellipse-0-coverage",
                             "ellipse-0-two-phase-coverage"]
    assert lines[1].startswith("resuming: 1 of 4 runs kept")
    assert sorted(p.name for p in unfinished.iterdir()) == [TRIAL_FILE, "metrics.json"]
    assert _stable(again) == _stable(first)


def test_another_seed_or_a_failed_trial_is_not_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[str] = []
    monkeypatch.setattr(_search, "run_experiment", _fake_run(calls, fail="circle-0-coverage"))
    first = _suite(tmp_path)
    assert first["baseline"]["circle"]["failed"] == 1
    assert not (tmp_path / "trials" / "circle-0-coverage" / TRIAL_FILE).exists()

    calls.clear()
    monkeypatch.setattr(_search, "run_experiment", _fake_run(calls))
    again = _suite(tmp_path)
    assert calls == ["circle-0-coverage"]  # the failure is tried again, the rest kept
    assert again["baseline"]["circle"]["failed"] == 0 and again["kept_runs"] == 3

    calls.clear()
    _suite(tmp_path, seed=1)  # other placements and seeds: nothing is kept
    assert len(calls) == 4


def test_a_resumed_full_run_does_not_claim_the_wall_time_target() -> None:
    summary = {"shapes": [], "trials": _search.DEFAULT_TRIALS, "wall_time_s": 10.0}
    assert _search.search_targets(summary)["wall_time_s"]["value"] == 10.0
    resumed = _search.search_targets({**summary, "kept_runs": 3})["wall_time_s"]
    assert resumed["value"] is None and resumed["met"] is None


# --- the workers' tie to their parent ------------------------------------------------------


class _Exited(Exception):
    pass


def test_the_watchdog_ends_the_worker_once_its_parent_has_gone() -> None:
    parents = iter([40, 40, 40, 1])
    slept: list[float] = []

    def exit_now(code: int) -> None:
        raise _Exited(code)

    with pytest.raises(_Exited, match="1"):
        _search._watch_parent(40, 0.25, getppid=lambda: next(parents), sleep=slept.append,
                              exit_now=exit_now)
    assert slept == [0.25, 0.25, 0.25]


def test_a_worker_orphaned_before_its_initializer_exits_at_once(
    monkeypatch: pytest.MonkeyPatch
) -> None:
    def exit_now(code: int) -> None:
        raise _Exited(code)

    # Not on this process: the test runner must not die with its parent.
    monkeypatch.setattr(_search, "_die_with_parent", lambda: True)
    monkeypatch.setattr(os, "_exit", exit_now)
    with pytest.raises(_Exited):
        _search._init_worker(os.getppid() + 1)


# --- kill -9 of the suite, in a subprocess -------------------------------------------------

#: The suite with two workers. Its fake run writes a file, then records the worker's pid and
#: its parent-death signal; the ellipse's run then never ends, so the suite is killed with
#: one trial finished and one running. argv: out dir, pid dir, "watchdog" to leave prctl out.
_SCRIPT = r"""
import ctypes, os, sys, time
from pathlib import Path
from hapticframe import BenchOptions
from hapticframe_bench import _search

out, pids, mode = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
if mode == "watchdog":
    _search._die_with_parent = lambda: False

def pdeathsig():
    value = ctypes.c_int(-1)
    ctypes.CDLL(None).prctl(2, ctypes.byref(value), ctypes.c_ulong(0), ctypes.c_ulong(0),
                            ctypes.c_ulong(0))
    return value.value

def fake_run(experiment, out_dir, *, overwrite, echo):
    run = Path(out_dir)
    run.mkdir(parents=True)
    (run / "partial.txt").write_text("the run's first file")
    (pids / f"{os.getpid()}.{run.name}").write_text(str(pdeathsig()))
    while run.name.startswith("ellipse"):
        time.sleep(5)
    return {"object_found": True, "centroid_error_m": 0.02, "hausdorff_est_to_true_m": 0.01,
            "hausdorff_true_to_est_m": 0.02, "movements": 6, "ems_phase1": 2,
            "ems_phase2": 4, "object_interactions": 3, "max_force_n": 40.0,
            "wall_time_s": 1.0}

_search.run_experiment = fake_run
_search.run_suite(BenchOptions(out_dir=out, trials=1, seed=0, workers=2,
                               echo=lambda line: print(line, flush=True)),
                  shapes=("circle", "ellipse"), planners={"search": "two-phase-coverage"})
"""


def _children(parent: int) -> set[int]:
    """Pids whose parent is ``parent``, from /proc."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue  # gone meanwhile
            if int(stat.rsplit(")", 1)[1].split()[1]) == parent:
                found.add(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    """A running process (a zombie is dead: an init that reaps nothing keeps them)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def _wait_for(condition: Callable[[], bool], bound_s: float, what: str,
              process: subprocess.Popen[str] | None = None, log: Path | None = None) -> None:
    deadline = time.monotonic() + bound_s
    while not condition():
        if process is not None and process.poll() is not None:
            output = log.read_text() if log is not None else ""
            pytest.fail(f"the suite ended (exit {process.returncode}) before {what}:\n{output}")
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {bound_s:.0f} s")
        time.sleep(0.05)


@pytest.mark.skipif(not sys.platform.startswith("linux"),
                    reason="reads /proc; PR_SET_PDEATHSIG is Linux's")
@pytest.mark.parametrize("mode", ["prctl", "watchdog"])
def test_kill_9_leaves_no_worker_and_a_rerun_resumes(
    mode: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out, pids, log = tmp_path / "out", tmp_path / "pids", tmp_path / "suite.log"
    pids.mkdir()
    # The subprocess imports this checkout's code, as this process does.
    paths = {str(Path(m.__file__ or "").resolve().parents[1]) for m in (sys.modules["hapticframe"],
                                                                       _search)}
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [*sorted(paths), *filter(None, [os.environ.get("PYTHONPATH")])])}
    finished = out / "trials" / "circle-0-two-phase-coverage" / TRIAL_FILE
    workers: set[int] = set()
    with log.open("w") as sink:
        suite = subprocess.Popen([sys.executable, "-c", _SCRIPT, str(out), str(pids), mode],
                                 stdout=sink, stderr=subprocess.STDOUT, env=env, text=True)
    try:
        _wait_for(lambda: finished.exists() and any(p.name.endswith(
            "ellipse-0-two-phase-coverage") for p in pids.iterdir()),
            START_WAIT_S, "one trial finished and the other running", suite, log)
        workers = _children(suite.pid) | {int(p.name.split(".")[0]) for p in pids.iterdir()}
        suite.send_signal(signal.SIGKILL)
        suite.wait()
        _wait_for(lambda: not any(map(_alive, workers)), DEATH_WAIT_S,
                  f"workers {sorted(filter(_alive, workers))} outlived their parent")
    finally:
        if suite.poll() is None:
            suite.kill()
            suite.wait()
        for pid in filter(_alive, workers):  # only what this test started, if it failed
            os.kill(pid, signal.SIGKILL)
    assert workers, "no worker was seen"
    expected = 0 if mode == "watchdog" else int(signal.SIGKILL)
    assert {int(p.read_text()) for p in pids.iterdir()} == {expected}
    # The killed suite left the running trial's first file, and no record for it.
    hung = out / "trials" / "ellipse-0-two-phase-coverage"
    assert (hung / "partial.txt").exists() and not (hung / TRIAL_FILE).exists()
    assert not (out / "search.json").exists()

    # The re-run keeps the finished trial, runs the other from scratch (the fake asserts an
    # empty directory) and writes the summary of an uninterrupted run.
    calls: list[str] = []
    monkeypatch.setattr(_search, "run_experiment", _fake_run(calls))
    lines: list[str] = []
    resumed = _suite(out, lines, **TWO_RUNS)
    assert calls == ["ellipse-0-two-phase-coverage"]
    assert lines[1].startswith("resuming: 1 of 2 runs kept")
    assert any(ln.startswith("[  1/2] circle") and "kept from an earlier run" in ln
               for ln in lines)
    assert not (hung / "partial.txt").exists() and (hung / TRIAL_FILE).exists()
    assert resumed["kept_runs"] == 1 and resumed["circle"]["completed"] == 1
    uninterrupted = _suite(tmp_path / "again", **TWO_RUNS)
    assert _stable(resumed) == _stable(uninterrupted)
