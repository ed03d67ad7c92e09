"""``hapticframe sweep``: points, trials, failures as rows, the report (issue 18 §3, §6)."""

from __future__ import annotations

import importlib.util
import json
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from hapticframe import UsageError
from hapticframe._config import load_file
from hapticframe._config._overrides import parse_overrides
from hapticframe.cli._cli import main
from hapticframe.sweep._sweep import (
    Point,
    SweepOptions,
    TrialTask,
    Vary,
    _gather,
    accuracy_measure,
    make_executor,
    pareto_front,
    parse_vary,
    plan_points,
    run_sweep,
    run_trial,
)
from hapticframe.sweep._sweep_report import render_markdown

from .test_overrides import TINY


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY, encoding="utf-8")
    return path


# --- planning --------------------------------------------------------------------------------


def test_vary_parses_a_path_and_yaml_values() -> None:
    assert parse_vary("bhm.hinge_spacing_m=0.025,0.05") == Vary("bhm.hinge_spacing_m",
                                                                (0.025, 0.05))
    with pytest.raises(UsageError, match="PATH=V1,V2"):
        parse_vary("bhm.hinge_spacing_m")


def test_one_at_a_time_changes_one_knob_and_skips_the_files_value() -> None:
    varies = [Vary("bhm.h", (0.025, 0.05, 0.1)), Vary("run.n", (1, 2))]
    points = plan_points(varies, {"bhm.h": 0.05, "run.n": 2})
    assert [p.label for p in points] == ["baseline", "bhm.h=0.025", "bhm.h=0.1", "run.n=1"]
    assert points[0].is_baseline and points[1].values == (("bhm.h", 0.025),)


def test_grid_runs_every_combination_once() -> None:
    varies = [Vary("a", (1, 2)), Vary("b", (True, False))]
    points = plan_points(varies, {"a": 1, "b": True}, grid=True)
    assert [p.label for p in points] == ["baseline", "a=1, b=false", "a=2, b=true",
                                         "a=2, b=false"]
    # True is not 1: a boolean knob never matches a count.
    assert len(plan_points([Vary("a", (1,))], {"a": True})) == 2


def test_pareto_front_keeps_what_nothing_beats() -> None:
    # (time, cost): the third is slower and worse than the first; the fourth ties no one.
    points = [(1.0, 0.5), (2.0, 0.2), (3.0, 0.6), (4.0, 0.1), (2.0, 0.3)]
    assert pareto_front(points) == [0, 1, 3]
    assert pareto_front([]) == []


def test_the_accuracy_measure_follows_the_metrics_reported() -> None:
    measure = accuracy_measure(["movements", "centroid_error_m"])
    assert measure is not None and measure[0] == "centroid_error_m" and measure[2](0.1) == 0.1
    measure = accuracy_measure(["contact_balanced_accuracy", "first_contact_error_s"])
    assert measure is not None and measure[2](0.75) == pytest.approx(0.25)
    # A perception run that also maps: the classifier's accuracy is what is traded.
    measure = accuracy_measure(["centroid_error_m", "contact_balanced_accuracy"])
    assert measure is not None and measure[0] == "contact_balanced_accuracy"
    measure = accuracy_measure(["map_auc"])
    assert measure is not None and measure[2](0.9) == pytest.approx(0.1)
    assert accuracy_measure(["movements"]) is None


# --- one trial -------------------------------------------------------------------------------


def _task(tiny: Path, out: Path, *overrides: str, timeout_s: float | None = None) -> TrialTask:
    return TrialTask(0, 0, 3, load_file(tiny),
                     parse_overrides(["run.max_movements=1", *overrides]), str(out),
                     timeout_s)


def test_a_trial_is_measured_and_reproducible(tiny: Path, tmp_path: Path) -> None:
    first = run_trial(_task(tiny, tmp_path / "a"))
    second = run_trial(_task(tiny, tmp_path / "b"))
    assert first["status"] == "ok", first["error"]
    assert first["steps"] > 0 and first["wall_time_s"] > 0 and first["cpu_time_s"] >= 0
    assert first["peak_rss_bytes"] > 10 * 2**20
    assert first["wall_time_per_step_s"] == pytest.approx(first["wall_time_s"] / first["steps"])

    def accuracy(row: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in row["metrics"].items() if k != "wall_time_s"}

    assert accuracy(first) == accuracy(second) and first["metrics"]["movements"] == 1
    record = json.loads((tmp_path / "a" / "run.json").read_text(encoding="utf-8"))
    assert record["overrides"][0]["set"] == "run.max_movements=1"


def test_an_exception_and_a_nan_metric_are_rows(tiny: Path, tmp_path: Path,
                                                monkeypatch: Any) -> None:
    import hapticframe.run._run as run_module

    def broken(*args: Any, **kwargs: Any) -> Any:
        raise FloatingPointError("the fit diverged")

    monkeypatch.setattr(run_module, "run_experiment", broken)
    row = run_trial(_task(tiny, tmp_path / "x"))
    assert (row["status"], row["error"]) == ("failed", "FloatingPointError: the fit diverged")
    monkeypatch.setattr(run_module, "run_experiment",
                        lambda *a, **k: {"centroid_error_m": math.nan, "movements": 1})
    row = run_trial(_task(tiny, tmp_path / "y"))
    assert row["status"] == "nan" and "centroid_error_m" in row["error"]


def test_a_trial_past_its_limit_is_a_timeout_row(tiny: Path, tmp_path: Path) -> None:
    row = run_trial(_task(tiny, tmp_path / "t", timeout_s=1e-3))
    assert row["status"] == "timeout" and "--timeout-s" in row["error"]


def test_a_worker_that_dies_or_hangs_is_a_row(tiny: Path, tmp_path: Path,
                                              monkeypatch: Any) -> None:
    import hapticframe.sweep._sweep_trials as sweep

    release = threading.Event()

    def fake(task: TrialTask) -> dict[str, Any]:
        if task.trial == 0:
            raise MemoryError("killed")
        release.wait(5)  # hangs past the limit (the thread's alarm cannot fire)
        return {}

    monkeypatch.setattr(sweep, "run_trial", fake)
    monkeypatch.setattr(sweep, "_GRACE_S", 0.0)
    tasks = [TrialTask(0, i, i, load_file(tiny), (), str(tmp_path / str(i)), 0.05)
             for i in range(2)]
    seen: list[str] = []
    with ThreadPoolExecutor(2) as pool:
        rows = _gather(pool, tasks, 2, 0.05, lambda row, _running: seen.append(row["status"]))
        release.set()
    assert [r["status"] for r in rows] == ["failed", "timeout"]
    assert "MemoryError" in rows[0]["error"] and sorted(seen) == ["failed", "timeout"]


# --- whole sweeps ----------------------------------------------------------------------------


def test_sweep_writes_table_front_and_figure(tiny: Path, tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "sweep"
    assert main(["sweep", str(tiny), "--vary", "run.max_movements=1,2",
                 "--vary", "bhm.hinge_spacing_m=0.1,-1", "--trials", "1", "--workers", "1",
                 "--set", "planner.line_spacing_m=0.06", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "[3/3]" in printed and "Pareto front" in printed
    result = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    labels = [p["label"] for p in result["points"]]
    # 2 is the file's value: the baseline point stands for it.
    assert labels == ["baseline", "run.max_movements=1", "bhm.hinge_spacing_m=0.1",
                      "bhm.hinge_spacing_m=-1"]
    statuses = {p["label"]: p["status"] for p in result["points"]}
    assert statuses["bhm.hinge_spacing_m=-1"] == "invalid"
    assert all(statuses[label] == "ok" for label in labels[:3])
    assert "came from --set" in result["points"][3]["errors"][0]
    assert [k["baseline"] for k in result["knobs"]] == [2, 0.05]
    assert result["accuracy"]["metric"] == "centroid_error_m"
    assert len(result["runs"]) == 3 and result["seeds"] == [3]
    baseline = result["points"][0]
    assert baseline["cost"]["wall_time_s"] > 0 and baseline["metrics"]["movements"] == 2
    # Every trial's run.json says what the point changed, with the sweep's own settings.
    run = json.loads((out / "points" / "p001" / "trial-0" / "run.json").read_text("utf-8"))
    assert [o["set"] for o in run["overrides"]] == [
        "planner.line_spacing_m=0.06", "run.max_movements=1", "run.figures=false",
        "run.record=false", "seed=3"]
    report = (out / "sweep.md").read_text(encoding="utf-8")
    assert "## run.max_movements" in report and "## bhm.hinge_spacing_m" in report
    assert "## Pareto front" in report and "invalid" in report
    assert (out / "pareto.png").stat().st_size > 1000


def test_a_sweep_whose_every_trial_times_out_still_reports(tiny: Path, tmp_path: Path) -> None:
    lines: list[str] = []
    result = run_sweep(tiny, tmp_path / "s", SweepOptions(
        varies=(Vary("run.max_movements", (1,)),), trials=1, workers=1, timeout_s=1e-3,
        echo=lines.append))
    assert [p["status"] for p in result["points"]] == ["timeout", "timeout"]
    assert result["front"] == [] and "timeout" in (tmp_path / "s" / "sweep.md").read_text("utf-8")
    assert (tmp_path / "s" / "pareto.png").exists()


def test_declared_knobs_are_swept(tiny: Path, tmp_path: Path, monkeypatch: Any) -> None:
    import hapticframe.sweep._sweep as sweep

    monkeypatch.setattr(sweep, "_declared", lambda experiment: [
        Vary("run.max_movements", (1, 2), "fewer movements: faster, may miss")])
    captured: dict[str, Any] = {}

    def fake_gather(executor: Any, tasks: Any, workers: int, timeout_s: Any,
                    on_row: Any, **options: Any) -> list[dict[str, Any]]:
        captured["tasks"] = tasks
        return []

    monkeypatch.setattr(sweep, "_gather", fake_gather)
    result = run_sweep(tiny, tmp_path / "d", SweepOptions(declared=True, trials=2, workers=1,
                                                          echo=lambda _l: None))
    assert [p["label"] for p in result["points"]] == ["baseline", "run.max_movements=1"]
    assert result["knobs"][0]["trades"] == "fewer movements: faster, may miss"
    assert [t.seed for t in captured["tasks"]] == [3, 4, 3, 4]


def test_nothing_to_vary_and_bad_options_are_usage_errors(tiny: Path, tmp_path: Path,
                                                          capsys: Any) -> None:
    assert main(["sweep", str(tiny), "--out", str(tmp_path / "n")]) == 2
    assert "nothing to vary" in capsys.readouterr().err
    assert main(["sweep", str(tiny), "--vary", "nope.x=1", "--out", str(tmp_path / "n")]) == 2
    assert "neither a component id" in capsys.readouterr().err
    with pytest.raises(UsageError, match="unknown executor"), make_executor("mpi", 1):
        pass


def test_markdown_lists_a_grid_point_under_each_of_its_knobs() -> None:
    point = {"label": "a=1, b=2", "values": [{"path": "a", "value": 1}, {"path": "b", "value": 2}],
             "status": "ok", "trials": 1, "trials_ok": 1, "errors": [],
             "metrics": {"centroid_error_m": 0.01}, "cost": {"wall_time_s": 1.0},
             "front": True, "accuracy_cost": 0.01}
    base = {**point, "label": "baseline", "values": [], "front": False}
    text = render_markdown({
        "experiment_file": "x.yaml", "mode": "grid", "trials": 1, "seeds": [0], "workers": 1,
        "executor": "process", "points": [base, point], "accuracy": {
            "metric": "centroid_error_m", "description": "mean centroid error (m)"},
        "knobs": [{"path": "a", "values": [1], "baseline": 0},
                  {"path": "b", "values": [2], "baseline": 0}]})
    assert text.count("| **a=1, b=2** |") == 2 and "| a=1, b=2 | 0.01 | – | 1 | – |" in text


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed is not installed (the distributed extra)")
def test_a_dask_local_cluster_gives_the_same_accuracy(tiny: Path, tmp_path: Path) -> None:
    def figures(executor: str) -> list[Any]:
        result = run_sweep(tiny, tmp_path / executor, SweepOptions(
            varies=(Vary("run.max_movements", (1,)),), trials=2, workers=1, executor=executor,
            echo=lambda _l: None))
        return [(p["label"], p["status"], {k: v for k, v in p["metrics"].items()
                                          if k != "wall_time_s"}) for p in result["points"]]

    assert figures("dask") == figures("process")


def test_points_are_frozen_records() -> None:
    assert Point("baseline").is_baseline and not Point("x=1", (("x", 1),)).is_baseline


def test_a_sweep_into_a_directory_another_command_writes_is_refused(
        tiny: Path, tmp_path: Path, capsys: Any) -> None:
    # Issue 26 §2: sweep takes the output directory's lock as run does (found by
    # `hapticframe bench fuzz`, family "writers": a sweep wrote its points beside a holder).
    from hapticframe import lock_directory

    out = tmp_path / "busy"
    out.mkdir()
    with lock_directory(out, "run"):
        code = main(["sweep", str(tiny), "--vary", "run.max_movements=1", "--trials", "1",
                     "--workers", "1", "--out", str(out)])
        assert code == 2
        assert "is in use by run" in capsys.readouterr().err
        assert sorted(p.name for p in out.iterdir()) == [".hapticframe.lock"]
