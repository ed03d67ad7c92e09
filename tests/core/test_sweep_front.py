"""What the real sweeps of issue 18 §4 showed the sweep report needed: a search that misses
the object kept off the front, a CPU-time front beside the wall-time one on a busy machine,
knobs that buy nothing named, readable declared values."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import Knob
from hapticframe._config import load_file
from hapticframe.sweep._format import unchanged
from hapticframe.sweep._sweep import (
    TrialTask,
    _declared,
    _mark_front,
    _mark_nan_against_baseline,
    _tidy,
    accuracy_measure,
    make_executor,
    run_trial,
)
from hapticframe.sweep._sweep_report import render_markdown

from .test_overrides import TINY


def _point(label: str, found: float, error: float, wall: float, cpu: float,
           values: tuple[tuple[str, Any], ...] = ()) -> dict[str, Any]:
    return {"label": label, "values": [{"path": p, "value": v} for p, v in values],
            "status": "ok", "trials": 3, "trials_ok": 3, "errors": [],
            "metrics": {"object_found": found, "centroid_error_m": error},
            "metrics_std": {}, "cost": {"wall_time_s": wall, "cpu_time_s": cpu}}


def _points() -> list[dict[str, Any]]:
    return [
        _point("baseline", 1.0, 0.018, 1.1, 0.46),
        # Misses the object and ends early: fastest, but no trade anyone wants.
        _point("j.cutoff_hz=10", 0.0, 0.18, 0.17, 0.08, (("j.cutoff_hz", 10.0),)),
        _point("j.cutoff_hz=6", 1.0, 0.008, 0.64, 0.34, (("j.cutoff_hz", 6.0),)),
        # Slower on the clock (a busy neighbour) though cheaper in CPU than the baseline.
        _point("b.h=0.1", 1.0, 0.012, 1.3, 0.30, (("b.h", 0.1),)),
        _point("b.h=0.025", 1.0, 0.007, 3.6, 0.65, (("b.h", 0.025),)),
    ]


def test_a_point_that_misses_the_object_is_kept_off_both_fronts() -> None:
    points = _points()
    _mark_front(points, accuracy_measure(["centroid_error_m", "object_found"]))
    front = [p["label"] for p in points if p["front"]]
    front_cpu = [p["label"] for p in points if p["front_cpu"]]
    assert front == ["j.cutoff_hz=6", "b.h=0.025"]
    assert front_cpu == ["j.cutoff_hz=6", "b.h=0.1", "b.h=0.025"]
    assert points[1]["off_front"] == "found the object in 0% of its trials, the best points in 100%"
    assert points[1]["accuracy_cost"] == 0.18  # still plotted, with its cost


def test_the_cpu_front_differs_where_the_wall_clock_waited() -> None:
    points = _points()
    points[2]["metrics"]["centroid_error_m"] = 0.013  # now b.h=0.1 is cheaper and better
    _mark_front(points, accuracy_measure(["centroid_error_m", "object_found"]))
    assert [p["label"] for p in points if p["front_cpu"]] == ["b.h=0.1", "b.h=0.025"]
    assert [p["label"] for p in points if p["front"]] == ["j.cutoff_hz=6", "b.h=0.1",
                                                          "b.h=0.025"]


def test_without_a_found_metric_nothing_is_kept_off() -> None:
    points = [{**p, "metrics": {"x_balanced_accuracy": 1 - p["metrics"]["centroid_error_m"]}}
              for p in _points()]
    _mark_front(points, accuracy_measure(["x_balanced_accuracy"]))
    assert all(p["off_front"] is None for p in points)
    assert points[1]["front"]  # fastest, and nothing says it missed anything


def test_a_knob_that_changes_no_accuracy_metric_is_named() -> None:
    same = [_point("baseline", 1.0, 0.018, 1.0, 0.4), _point("g=0.02", 1.0, 0.018, 1.3, 0.4)]
    assert unchanged(same, ["object_found", "centroid_error_m"])
    assert not unchanged([*same, _point("g=0.04", 1.0, 0.019, 1.0, 0.4)],
                          ["object_found", "centroid_error_m"])
    assert not unchanged(same[:1], ["centroid_error_m"])


def test_the_report_states_the_load_both_fronts_and_what_bought_nothing() -> None:
    points = _points() + [_point("g.cell=0.02", 1.0, 0.018, 1.2, 0.45, (("g.cell", 0.02),))]
    _mark_front(points, accuracy_measure(["centroid_error_m", "object_found"]))
    result = {"experiment_file": "s.yaml", "mode": "one at a time", "trials": 3,
              "seeds": [7, 8, 9], "workers": 2, "executor": "process", "overrides": [],
              "knobs": [{"path": "j.cutoff_hz", "values": [6.0, 10.0], "baseline": 3.0,
                         "trades": ""},
                        {"path": "g.cell", "values": [0.02], "baseline": 0.01, "trades": ""}],
              "accuracy": {"metric": "centroid_error_m", "description": "mean centroid error"},
              "points": points,
              "machine": {"cpu_count": 2, "load_average_1min": {"start": 4.4, "end": 5.1}}}
    text = render_markdown(result)
    assert "Machine load (1-minute average) 4.4 at the start and 5.1 at the end, on 2 CPUs" \
        in text
    assert "Against wall time:" in text and "Against CPU time:" in text
    assert "- j.cutoff_hz=10: found the object in 0% of its trials" in text
    knob_g = text.split("## g.cell")[1].split("## ")[0]
    assert "buys nothing" in knob_g
    assert "buys nothing" not in text.split("## j.cutoff_hz")[1].split("## ")[0]


def test_declared_range_values_are_tidied(monkeypatch: Any) -> None:
    assert _tidy(0.017099759466766964) == 0.0171
    assert _tidy(0.05) == 0.05 and _tidy(0.0) == 0.0 and _tidy(40) == 40 and _tidy("a") == "a"
    knob = Knob("tolerance", "a looser stop", low=0.005, high=0.2, scale="log", points=4)
    assert 0.017099759466766964 in [round(v, 18) for v in knob.sweep_values()]
    monkeypatch.setattr("hapticframe._knobs.declared_knobs", lambda experiment: [("bhm", knob)])
    (vary,) = _declared(object())
    assert vary.path == "bhm.tolerance" and vary.values == (0.005, 0.0171, 0.0585, 0.2)


# --- what the perception sweep showed ---------------------------------------------------------


def _torch_product() -> float:
    import torch

    return float(torch.ones(200_000, dtype=torch.float64).mul(2.0).sum())


def test_workers_do_not_inherit_a_parent_that_ran_torch_threads() -> None:
    """A pool forked from a process whose torch had run an OpenMP region waited for ever
    in its first torch call (the perception sweep's workers did, in libgomp)."""
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        torch.ones(2_000_000).mul(2.0).sum()  # an OpenMP region here, in the parent
        with make_executor("process", 1) as pool:
            assert pool.submit(_torch_product).result(timeout=120) == 400_000.0
    finally:
        torch.set_num_threads(threads)


def _tiny_task(tiny: Path, out: Path) -> TrialTask:
    return TrialTask(0, 0, 1, load_file(tiny), (), str(out))


def test_a_runs_warnings_are_counted_not_printed(tmp_path: Path, monkeypatch: Any,
                                                  capsys: Any) -> None:
    import hapticframe.run._run as run_module

    def warns(*args: Any, **kwargs: Any) -> dict[str, Any]:
        for _ in range(5):
            warnings.warn("lasso encoding: 1 of 1 rows did not converge", RuntimeWarning,
                          stacklevel=1)
        return {"centroid_error_m": 0.01}

    tiny = tmp_path / "tiny.yaml"
    tiny.write_text(TINY, encoding="utf-8")
    monkeypatch.setattr(run_module, "run_experiment", warns)
    row = run_trial(_tiny_task(tiny, tmp_path / "x"))
    assert row["status"] == "ok"
    assert row["warnings"] == {"count": 5, "messages": [
        "RuntimeWarning: lasso encoding: 1 of 1 rows did not converge"]}
    assert "lasso" not in capsys.readouterr().err


def test_a_metric_nan_in_the_baseline_too_fails_nothing(tmp_path: Path,
                                                        monkeypatch: Any) -> None:
    import hapticframe.run._run as run_module

    tiny = tmp_path / "tiny.yaml"
    tiny.write_text(TINY, encoding="utf-8")
    monkeypatch.setattr(run_module, "run_experiment", lambda *a, **k: {
        "contact_balanced_accuracy": 0.94, "max_measured_force_n": math.nan})
    row = run_trial(_tiny_task(tiny, tmp_path / "x"))
    assert row["status"] == "ok" and row["non_finite"] == ["max_measured_force_n"]
    baseline = {**row, "point": 0}
    other = {**row, "point": 1, "metrics": {**row["metrics"], "x_count": math.nan},
             "non_finite": ["max_measured_force_n", "x_count"]}
    finite_in_baseline = {**baseline, "metrics": {**baseline["metrics"], "x_count": 3}}
    _mark_nan_against_baseline([baseline, other])
    assert baseline["status"] == other["status"] == "ok"
    _mark_nan_against_baseline([finite_in_baseline, other])
    assert (other["status"], other["error"]) == ("nan", "non-finite metrics: x_count")


def test_a_large_sweep_names_only_its_front_and_baseline(monkeypatch: Any, tmp_path: Path) -> None:
    import hapticframe.plotting as plotting
    from hapticframe.sweep._sweep_report import LABEL_ALL_UP_TO, save_pareto_figure

    captured: dict[str, Any] = {}
    monkeypatch.setattr(plotting, "save_figure", lambda figure, path: captured.update(f=figure))
    points = [{"label": f"k={i}", "accuracy_cost": 1.0 + (i % 7) / 10,
               "cost": {"cpu_time_s": 1.0 + i / 10}, "front_cpu": i in (0, 3, 9),
               "off_front": False} for i in range(55)]
    assert save_pareto_figure(tmp_path / "pareto.png", {
        "points": points, "accuracy": {"description": "cost"}, "experiment_file": "x.yaml"})
    named = sorted(t.get_text() for t in captured["f"].axes[0].texts)
    assert named == ["k=0", "k=3", "k=9"]  # the baseline (k=0) is on the front here
    few = points[:LABEL_ALL_UP_TO]
    save_pareto_figure(tmp_path / "few.png", {
        "points": few, "accuracy": {"description": "cost"}, "experiment_file": "x.yaml"})
    assert len(captured["f"].axes[0].texts) == LABEL_ALL_UP_TO


def _swept(trials: int) -> dict[str, Any]:
    """A sweep's result as run_sweep summarises it: eight hinge spacings over ``trials`` seeded
    trials each, close together in CPU time (so that their labels crowd)."""
    from hapticframe.sweep._sweep import Point, _summarise_point

    rng = np.random.default_rng(3)
    summaries = []
    for number in range(8):
        values = () if number == 0 else (("bhm.hinge_spacing_m", 0.01 * number),)
        point = Point("baseline" if number == 0 else f"bhm.hinge_spacing_m={0.01 * number:g}",
                      values)
        rows = [{"status": "ok", "metrics": {"object_found": 1.0,
                                             "centroid_error_m": 0.01 + 0.004 * rng.random()},
                 "wall_time_s": 2.0 + rng.random(), "cpu_time_s": 0.30 + 0.02 * rng.random()}
                for _ in range(trials)]
        summaries.append(_summarise_point(point, rows))
    measure = accuracy_measure(["object_found", "centroid_error_m"])
    _mark_front(summaries, measure)
    assert measure is not None
    return {"points": summaries, "experiment_file": "x.yaml", "trials": trials,
            "accuracy": {"metric": measure[0], "description": measure[1]}}


def _draw(monkeypatch: Any, tmp_path: Path, result: dict[str, Any]) -> Any:
    import hapticframe.plotting as plotting
    from hapticframe.sweep._sweep_report import save_pareto_figure

    captured: dict[str, Any] = {}
    save = plotting.save_figure

    def capture(figure: Any, path: Path) -> Path:
        captured["f"] = figure
        return save(figure, path)

    monkeypatch.setattr(plotting, "save_figure", capture)
    assert save_pareto_figure(tmp_path / "pareto.png", result)
    assert (tmp_path / "pareto.png").stat().st_size > 0
    return captured["f"]


def test_pareto_png_draws_cpu_time_seed_spread_a_legend_inside_and_no_overprint(
        monkeypatch: Any, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.container import ErrorbarContainer

    result = _swept(trials=3)
    figure = _draw(monkeypatch, tmp_path, result)
    ax = figure.axes[0]
    assert "CPU time" in ax.get_xlabel()
    points = result["points"]
    # Error bars: one per point, x the CPU time's and y the accuracy's standard deviation
    # over the point's trials.
    bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 1 and bars[0].has_xerr and bars[0].has_yerr
    x_segments, y_segments = bars[0].lines[2]
    x_half = [float(np.ptp(s[:, 0])) / 2 for s in x_segments.get_segments()]
    y_half = [float(np.ptp(s[:, 1])) / 2 for s in y_segments.get_segments()]
    np.testing.assert_allclose(x_half, [p["cost_std"]["cpu_time_s"] for p in points])
    np.testing.assert_allclose(y_half, [p["metrics_std"]["centroid_error_m"] for p in points])
    assert min(x_half) > 0 and min(y_half) > 0
    # The points sit at their mean CPU time.
    centres = sorted(float(np.mean(s[:, 0])) for s in x_segments.get_segments())
    np.testing.assert_allclose(centres, sorted(p["cost"]["cpu_time_s"] for p in points))
    # The legend lies inside the figure and names the spread.
    renderer = figure.canvas.get_renderer()
    frame = figure.bbox
    assert len(figure.legends) == 1 and ax.get_legend() is None
    box = figure.legends[0].get_window_extent(renderer)
    assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0
    assert box.y1 <= ax.get_window_extent(renderer).y0  # below the axes, over no point
    assert any("seed spread" in t.get_text() for t in figure.legends[0].get_texts())
    # Every point named, no label over another, all inside the axes.
    labels = [t for t in ax.texts]
    assert sorted(t.get_text() for t in labels) == sorted(p["label"] for p in points)
    boxes = [t.get_window_extent(renderer) for t in labels]
    inside = ax.get_window_extent(renderer)
    for i, a in enumerate(boxes):
        assert inside.x0 <= a.x0 and a.x1 <= inside.x1 and inside.y0 <= a.y0 and a.y1 <= inside.y1
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (labels[i].get_text(), a, b)


def test_pareto_png_of_one_trial_per_point_draws_no_spread(monkeypatch: Any,
                                                           tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.container import ErrorbarContainer

    figure = _draw(monkeypatch, tmp_path, _swept(trials=1))
    assert not [c for c in figure.axes[0].containers if isinstance(c, ErrorbarContainer)]
    assert not any("seed spread" in t.get_text() for t in figure.legends[0].get_texts())
