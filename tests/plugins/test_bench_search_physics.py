"""``bench search-physics``: its registration and its report (issue 29 §3).

The suite itself runs searches in the mpm-sand world (minutes); these tests check what it
writes from a summary, and that it is registered like the other suites.
"""

from __future__ import annotations

import pytest

from hapticframe_bench import plugin
from hapticframe_bench._search_physics import (
    CONFIGURATIONS,
    WORLD_OVERRIDE,
    _calibration_experiment,
    _row,
    render_physics_markdown,
)


def _group(found: int) -> dict:
    return {"completed": 2, "found": found, "centroid_rmse_m": 0.012 if found else None,
            "ems_phase1": {"mean": 4.0, "std": 1.0}, "ems_phase2": {"mean": 2.0, "std": 0.5},
            "object_interactions": {"mean": 3.0, "std": 0.0},
            "hausdorff_m": {"mean": 0.02, "std": 0.005} if found else {"mean": None}}


def _summary() -> dict:
    results = {key: {"circle": _row(_group(2 if "sandbox" in key else 1)),
                     "ellipse": _row(_group(0))} for _w, _l, key in CONFIGURATIONS}
    calibration = {
        "thresholds": {"jamming_force_n": 4.4, "jamming_rate_n_per_s": 2.5,
                       "contact_force_n": 4.5, "contact_rate_n_per_s": 4.4},
        "thresholds_per_recording": {"circle": {"jamming_force_n": 4.4}},
        "failure_zone": {"rupture_ratio": 1.1, "shear_band_angle_deg": 42.3,
                         "sector_half_angle_deg": 44.8, "initial_depth_m": 0.044,
                         "depth_decrement_m": 0.01, "depth_decrement_ratio": 0.5,
                         "onset_distance_m": [0.04, 0.03]},
    }
    return {"command": "c", "trials": 2, "seed": 0, "shapes": ["circle", "ellipse"],
            "results": results, "calibration": calibration, "wall_time_s": 12.0}


def test_registered_like_the_other_suites() -> None:
    specs = {s.name: s for s in plugin.hapticframe_benchmarks()}
    assert specs["search-physics"].factory == (
        "hapticframe_bench._search_physics:run_search_physics")
    assert WORLD_OVERRIDE == "robots[0].type=mpm-sand"


def test_report_has_every_configuration_and_the_parameter_table() -> None:
    text = render_physics_markdown(_summary())
    for _world, label, _key in CONFIGURATIONS:
        assert label in text
    assert "| circle | analytic sandbox | (a) defaults | 4.0 ± 1.0 | 2.0 ± 0.5 | 3.0 ± 0.0 " \
           "| 1.2 cm | 2.0 ± 0.5 cm | 2/2 |" in text
    assert "| ellipse | mpm-sand | (b) calibrated in the world |" in text
    assert "| – | – | 0/2 |" in text  # nothing found: no lengths
    # Rupture distance 1.1 x 4.4 cm against Table 3.1's 7.2 cm.
    assert "| rupture distance at 4.40 cm depth | 4.8 cm | 7.2 cm | 7.2 cm |" in text
    assert "| `jamming_force_n` | 4.40 N | – | 6.0 N |" in text


def test_calibration_experiment_floors_at_the_free_drag(tmp_path) -> None:
    data = _calibration_experiment(tmp_path)
    assert data["classifiers"][0]["config"] == {"calibration_force_floor": "free-drag"}
    assert data["sensors"][0]["config"]["path"] == str(tmp_path)


@pytest.mark.parametrize("group", [None, {}])
def test_row_of_a_missing_group_is_empty(group) -> None:
    row = _row(group)
    assert row["found"] is None and row["ems_phase1"] == (None, None)
