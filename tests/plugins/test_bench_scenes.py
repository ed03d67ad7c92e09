"""``bench search-scenes``: polygon rows and scenes of several objects (issue 19 §3-§4)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest

from hapticframe import BenchOptions, Scene
from hapticframe_bench._aggregate import aggregate_trials, trial_figures
from hapticframe_bench._placements import MULTI_SCENES, SHAPES, draw_placements
from hapticframe_bench._report import render_markdown
from hapticframe_bench._search import run_suite
from hapticframe_bench._template import search_experiment


def test_the_default_placements_are_unchanged_by_the_new_scenes():
    # Table 3.2's draws come first and alone: the same numbers as before the new shapes.
    placements = draw_placements(np.random.default_rng(0), 3)
    assert tuple(placements) == SHAPES
    rng = np.random.default_rng(0)
    orientation = float(rng.uniform(0.0, 180.0))
    assert placements["circle"][0].orientation_deg == orientation
    assert placements["circle"][0].parts == ()


@pytest.mark.parametrize("gap", [0.05, 0.15])
def test_multi_object_scenes_keep_their_gap_and_fit(gap):
    placements = draw_placements(np.random.default_rng(3), 4, shapes=tuple(MULTI_SCENES),
                                 gap_m=gap)
    for name, shapes in MULTI_SCENES.items():
        for placement in placements[name]:
            scene = Scene.model_validate({"objects": placement.scene_objects()})
            assert [p.shape for p in placement.parts] == list(shapes)
            assert scene.problems() == []
            outlines = [o.outline(128) for o in scene.objects]
            for i in range(len(outlines)):
                for j in range(i):
                    d = np.linalg.norm(outlines[i][:, None] - outlines[j][None], axis=2)
                    assert d.min() >= gap - 1e-12
            assert len(placement.to_dict()["parts"]) == len(shapes)


def test_a_gap_too_wide_is_refused_with_advice():
    with pytest.raises(ValueError, match="lower the gap"):
        draw_placements(np.random.default_rng(0), 1, shapes=("three-objects",), gap_m=0.6)


def _record(found: int, total: int, false: int) -> dict[str, Any]:
    metrics = {"object_found": found == total, "objects_total": total, "objects_found": found,
               "objects_missed": total - found, "false_blobs": false,
               "centroid_error_m": 0.01, "hausdorff_est_to_true_m": 0.02,
               "hausdorff_true_to_est_m": 0.03, "movements": 9}
    return {"status": "ok", "figures": trial_figures(metrics)}


def test_object_counts_are_summed_per_scene():
    group = aggregate_trials([_record(2, 2, 0), _record(1, 2, 1)])
    assert group["objects"] == {"objects_total": 4, "objects_found": 3, "objects_missed": 1,
                                "false_blobs": 1}
    assert group["found"] == 1
    # A one-object trial's figures carry no per-object counts.
    single = trial_figures({"object_found": True, "centroid_error_m": 0.01})
    assert "objects_total" not in single and "objects" not in aggregate_trials(
        [{"status": "ok", "figures": single}])


def _cheap(objects: Any, planner: str, seed: int, name: str) -> dict[str, Any]:
    data = search_experiment(objects, planner, seed, name)
    data["robots"][0]["config"] = {"control_rate_hz": 25.0}
    data["sensor_models"][0]["config"] = {"observation_spacing_m": 0.03}
    data["maps"] = [m for m in data["maps"] if m["id"] == "bhm"]
    data["maps"][0]["config"] = {"region_dependent_smoothing": False,
                                 "monte_carlo_samples": 20, "hinge_spacing_m": 0.08}
    return data


@pytest.mark.parametrize(("est_cm", "bridged"), [(0.5, False), (2.5, True)])
def test_the_report_says_when_the_level_set_bridges_a_concavity(est_cm, bridged):
    metrics = {"object_found": True, "centroid_error_m": 0.01,
               "hausdorff_est_to_true_m": est_cm / 100, "hausdorff_true_to_est_m": 0.01}
    group = aggregate_trials([{"status": "ok", "figures": trial_figures(metrics)}])
    summary = {"shapes": ["star"], "planners": {"search": "two-phase-coverage"},
               "star": group, "baseline": {"star": aggregate_trials([])}}
    report = render_markdown(summary)
    line = next(x for x in report.splitlines() if x.startswith("- star, two-phase-coverage"))
    # The star's hull strays 1.6 cm from its outline: 60 % of that is the dividing line.
    assert "convex hull lies up to" in line
    assert ("bridges the concavity" in line) is bridged


def test_a_tiny_scenes_run_reports_every_object(tmp_path):
    lines: list[str] = []
    options = BenchOptions(out_dir=tmp_path, trials=1, seed=0, quick=True, workers=1,
                           echo=lines.append)
    summary = run_suite(options, experiment_factory=_cheap, shapes=("two-objects",),
                        planners={"search": "two-phase-coverage"}, report_name="scenes")
    saved = json.loads((tmp_path / "scenes.json").read_text(encoding="utf-8"))
    assert saved["shapes"] == ["two-objects"]
    two = summary["two-objects"]
    assert two["completed"] == 1 and two["objects"]["objects_total"] == 2
    run = next(r for r in summary["runs"] if r["shape"] == "two-objects")
    assert len(run["placement"]["parts"]) == 2
    report = (tmp_path / "scenes.md").read_text(encoding="utf-8")
    assert "## Every object (scenes of several objects)" in report
    assert report == render_markdown(saved)
    assert any("found " in line and "/2" in line for line in lines)
