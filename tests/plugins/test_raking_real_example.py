"""The raking-real example: its summary line prints the scores against the streamed labels,
and its figure draws the truth beside the estimate, names the classes and shows every
legend entry."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, RunOutcome, SampleBatch
from hapticframe_raking import ObjectEstimate, RakingEstimator, RakingEstimatorConfig, load_trials
from hapticframe_raking._figures import (
    _TRACK_OFFSET,
    CLASS_NOTE,
    DEPTH_MEANING,
    DIRECTION_MEANING,
    estimate_figure,
)

ROOT = Path(__file__).resolve().parents[2]


def _two_trials() -> tuple[np.ndarray, ObjectEstimate, np.ndarray, np.ndarray, np.ndarray]:
    """Two 6-sample trials 1 s apart with known estimates and labels."""
    t = np.concatenate([0.1 * np.arange(6), 1.5 + 0.1 * np.arange(6)])
    distance = np.linspace(100.0, 10.0, 12)
    direction = np.repeat([0.0, 2.0], 6)
    depth = np.repeat([1.0, 0.0], 6)
    est_direction = np.array([0, 0, 1, 0, 0, 0, 2, 2, 2, 1, 2, 2])  # 10 of 12 right
    est_depth = np.array([1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 1])  # 11 of 12 right
    est = ObjectEstimate(distance + 4.0, np.full(12, 3.0),
                         np.eye(3)[est_direction] * 0.8 + 0.2 / 3,
                         np.eye(2)[est_depth] * 0.8 + 0.1)
    return t, est, distance, direction, depth


def _finite(line: object) -> np.ndarray:
    y = np.asarray(line.get_ydata(), dtype=np.float64)  # type: ignore[attr-defined]
    return y[np.isfinite(y)]


def test_the_figure_draws_the_truth_beside_the_estimate_and_names_the_classes() -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    t, est, distance, direction, depth = _two_trials()
    fig = estimate_figure(t, est, distance, direction, depth)
    try:
        dist_ax, dir_ax, depth_ax = fig.axes[:3]
        lines = {line.get_label(): line for line in dist_ax.get_lines()}
        np.testing.assert_allclose(_finite(lines["labelled distance (truth)"]), distance)
        np.testing.assert_allclose(_finite(lines["estimated distance"]), distance + 4.0)
        # A trial's line does not run on into the next trial.
        assert np.isnan(np.asarray(lines["labelled distance (truth)"].get_ydata())).sum() == 1
        assert "mean absolute error 4.0 mm" in dist_ax.get_title(loc="left")
        for ax, truth, proba, meaning, n, agree in (
                (dir_ax, direction, est.direction_proba, DIRECTION_MEANING, 3, "83.3 %"),
                (depth_ax, depth, est.depth_proba, DEPTH_MEANING, 2, "91.7 %")):
            lines = {line.get_label(): line for line in ax.get_lines()}
            np.testing.assert_allclose(_finite(lines["labelled class (truth)"]),
                                       truth + _TRACK_OFFSET)
            np.testing.assert_allclose(_finite(lines["most probable class (estimate)"]),
                                       proba.argmax(1) - _TRACK_OFFSET)
            assert [x.get_text() for x in ax.get_yticklabels()] == [
                f"class {k}" for k in range(n)]
            title = ax.get_title(loc="left")
            assert title.startswith(meaning) and title.endswith(f"{agree} of samples")
        assert fig.get_suptitle() == CLASS_NOTE
    finally:
        plt.close(fig)


def test_without_labels_the_figure_draws_no_truth() -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    t, est, *_ = _two_trials()
    fig = estimate_figure(t, est, None)
    try:
        labels = [line.get_label() for ax in fig.axes[:3] for line in ax.get_lines()]
        assert labels == ["estimated distance", "most probable class (estimate)",
                          "most probable class (estimate)"]
        assert "error" not in fig.axes[0].get_title(loc="left")
        assert fig.axes[1].get_title(loc="left") == DIRECTION_MEANING
    finally:
        plt.close(fig)


def test_every_legend_entry_is_drawn_inside_the_figure_beside_its_panel() -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    t, est, distance, direction, depth = _two_trials()
    fig = estimate_figure(t, est, distance, direction, depth)
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        expected = [["estimate ±1 std", "estimated distance", "labelled distance (truth)"]] + [
            ["labelled class (truth)", "most probable class (estimate)"]] * 2
        for ax, names in zip(fig.axes[:3], expected, strict=True):
            legend = ax.get_legend()
            assert legend is not None
            assert [x.get_text() for x in legend.get_texts()] == names
            assert len(legend.legend_handles) == len(names)
            assert all(h is not None and h.get_visible() for h in legend.legend_handles)
            box = legend.get_window_extent(renderer)
            figure_box = fig.bbox
            assert figure_box.x0 <= box.x0 and box.x1 <= figure_box.x1
            assert figure_box.y0 <= box.y0 and box.y1 <= figure_box.y1
            assert box.x0 >= ax.get_window_extent(renderer).x1  # beside, hiding no data
    finally:
        plt.close(fig)


def _stream(est: RakingEstimator, trials: list, labelled: bool) -> None:
    t0 = 0.0
    for trial in trials:
        channels: dict[str, np.ndarray] = {"taxel_force": trial.force}
        if labelled:
            channels |= {"distance_mm": trial.distance_mm,
                         "direction_class": trial.direction.astype(np.float64),
                         "depth_class": trial.depth.astype(np.float64)}
        t = t0 + 0.1 * np.arange(len(trial), dtype=np.float64)
        est.update(SampleBatch(t, channels))
        t0 += 0.1 * len(trial) + 1.0


def test_the_scores_are_those_of_the_streamed_labels_and_only_with_labels(
        tmp_path: Path) -> None:
    trials = load_trials("testing")[:3]
    scores = ("est_distance_mae_mm", "est_direction_accuracy", "est_depth_accuracy")
    for labelled in (True, False):
        est = RakingEstimator(RakingEstimatorConfig(pretrained=True),
                              BuildContext("est", np.random.default_rng(0)))
        _stream(est, trials, labelled)
        out = tmp_path / str(labelled)
        out.mkdir()
        metrics = est.finalize(RunOutcome(out_dir=out, scene=None, movements=(), components={},
                                           wall_time_s=0.0, figures=False))
        if not labelled:
            assert not set(scores) & set(metrics)
            continue
        _, e = est.estimates
        truth = np.concatenate([t.distance_mm for t in trials])
        assert metrics["est_distance_mae_mm"] == pytest.approx(
            np.mean(np.abs(e.distance_mm - truth)))
        assert metrics["est_direction_accuracy"] == pytest.approx(np.mean(
            e.direction_proba.argmax(1) == np.concatenate([t.direction for t in trials])))
        assert metrics["est_depth_accuracy"] == pytest.approx(np.mean(
            e.depth_proba.argmax(1) == np.concatenate([t.depth for t in trials])))


def test_the_example_run_prints_its_scores(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("matplotlib")
    from hapticframe.cli._cli import main
    from hapticframe.cli._common import short_number

    monkeypatch.chdir(ROOT)  # the example's paths are relative to the repository's root
    out = tmp_path / "run"
    # The shipped model, trained as examples/raking-train.yaml trains (its own test), in
    # place of the training step.
    assert main(["run", "examples/raking-real.yaml", "--out", str(out), "--set",
                 "estimator.model_dir=null", "--set", "estimator.pretrained=true"]) == 0
    summary = capsys.readouterr().out.strip().splitlines()[-1]
    metrics = json.loads((out / "metrics.json").read_text())
    saved = np.load(out / "estimates.npz")
    assert len(saved["timestamps_s"]) == sum(len(t) for t in load_trials("testing"))
    mae = float(np.mean(np.abs(saved["distance_mm"] - saved["true_distance_mm"])))
    assert metrics["estimator_distance_mae_mm"] == pytest.approx(mae)
    for key in ("estimator_distance_mae_mm", "estimator_direction_accuracy",
                "estimator_depth_accuracy"):
        assert f"{key}={short_number(metrics[key])}" in summary
    assert summary.index("estimator_depth_accuracy") < summary.index("wall_time_s")
    # The README shows this line (the shipped model is the one the training example trains).
    shown = [line for line in (ROOT / "README.md").read_text().splitlines()
             if line.startswith("results in runs/raking-real ")]
    assert len(shown) == 1
    for key in ("estimator_distance_mae_mm", "estimator_direction_accuracy",
                "estimator_depth_accuracy"):
        assert f"{key}={short_number(metrics[key])}," in shown[0]
    assert (out / "estimator-estimates.png").stat().st_size > 10_000
