"""What ``validate`` refuses of the occupancy grid: more cells than it may hold (issue 16)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse.yaml"


def test_a_cell_size_with_billions_of_cells_is_refused_with_the_estimate() -> None:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert data["maps"][0]["type"] == "occupancy-grid"
    data["maps"][0]["config"] = {"cell_size_m": 1e-5}
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    (issue,) = caught.value.issues
    assert issue.path == "maps[0].config.cell_size_m"
    assert "3.75e+09 cells over the 0.75 x 0.5 m region" in issue.message
    data["maps"][0]["config"] = {"cell_size_m": 0.001}  # 375,000 cells: fine
    assert "grid" in [c.id for c in validate_mapping(data).components]
