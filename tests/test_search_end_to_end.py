"""The README's main job: one complete autonomous search on the simulated sandbox."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[1]
REQUIRED = {
    "ems_phase1", "ems_phase2", "object_interactions", "centroid_error_m",
    "hausdorff_est_to_true_m", "hausdorff_true_to_est_m", "max_force_n", "wall_time_s",
}
FIGURES = {"logodds_phase1.png", "logodds_phase2.png", "bhm_mean.png", "bhm_std.png",
           "outline.png", "paths.png", "forces.png"}


def test_search_ellipse_finds_and_outlines_the_object(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["run", str(ROOT / "examples" / "search-ellipse.yaml"), "--out", str(out)]) == 0
    progress = [line for line in capsys.readouterr().out.splitlines() if line.startswith("EM ")]
    metrics = json.loads((out / "metrics.json").read_text())
    assert REQUIRED <= set(metrics)
    assert len(progress) == metrics["movements"] == metrics["ems_phase1"] + metrics["ems_phase2"]
    assert metrics["ems_phase1"] >= 2 and metrics["object_interactions"] >= 2
    assert metrics["object_found"] is True
    # A blind guess in a 75 x 50 cm region is ~20 cm off; the search must do far better.
    assert metrics["centroid_error_m"] < 0.03
    assert max(metrics["hausdorff_est_to_true_m"], metrics["hausdorff_true_to_est_m"]) < 0.06
    assert metrics["max_force_n"] <= 80.0
    assert FIGURES <= {p.name for p in out.glob("*.png")}
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        forces = trace["sensor/wrist/force_n"]
        assert forces.ndim == 2 and forces.shape[1] == 2 and np.all(np.isfinite(forces))
        assert len(trace["robot/arm/position_m"]) == len(forces)
        assert len(trace["sensor_model/failure-zone/targets"]) > 0


def test_an_object_touching_the_region_edge_is_searched_without_failure(tmp_path):
    # A circle whose rim touches the region's left edge: paths, kernels and maps all meet
    # the boundary at once. The run must finish, stay within the force limit and report
    # finite figures (whether the object is found is the benchmark's business).
    text = (ROOT / "examples" / "search-ellipse.yaml").read_text().replace(
        "- {shape: ellipse, center_m: [0.42, 0.21], semi_axes_m: [0.045, 0.025], "
        "orientation_deg: 35}",
        "- {shape: circle, center_m: [0.04, 0.30], radius_m: 0.04}",
    )
    assert "shape: circle" in text
    # It checks no figure: drawing them would only cost time.
    assert text.count("\nrun:\n") == 1 and "figures:" not in text
    text = text.replace("\nrun:\n", "\nrun:\n  figures: false\n")
    path = tmp_path / "edge.yaml"
    path.write_text(text.replace("../schemas/", str(ROOT / "schemas") + "/"))
    out = tmp_path / "edge"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 0
    assert not list(out.glob("*.png"))
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["max_force_n"] <= 80.0 and metrics["movements"] >= 1
    if metrics["object_found"]:
        assert np.isfinite(metrics["centroid_error_m"]) and metrics["centroid_error_m"] < 0.05
    else:
        assert metrics["centroid_error_m"] is None
