"""What ``validate`` refuses of the Bayesian Hilbert map: hinge grids the dense posterior
cannot hold (issue 16: ``hinge_spacing_m: 1e-5`` allocated 27.9 GiB), with the estimate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_mapping

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse.yaml"
FIELD = "maps[1].config.hinge_spacing_m"


def _with_bhm(config: dict[str, Any]) -> dict[str, Any]:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert data["maps"][1]["type"] == "bayesian-hilbert-map"
    data["maps"][1]["config"] = config
    return data


def test_a_hinge_spacing_with_billions_of_weights_is_refused_with_the_estimate() -> None:
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(_with_bhm({"hinge_spacing_m": 1e-5}))
    (issue,) = caught.value.issues
    assert issue.path == FIELD
    assert "3.75e+09 weights over the 0.75 x 0.5 m region" in issue.message
    assert "the limit is 5000" in issue.message


def test_the_limit_follows_the_region() -> None:
    # 8 mm hinges: 97 x 66 over the scene's region, but 28 x 28 over a 20 cm one.
    with pytest.raises(ExperimentError, match=r"6.4e\+03 weights"):
        validate_mapping(_with_bhm({"hinge_spacing_m": 0.008}))
    small = {"x_min_m": 0.3, "x_max_m": 0.5, "y_min_m": 0.1, "y_max_m": 0.3}
    assert validate_mapping(_with_bhm({"hinge_spacing_m": 0.008, "region": small}))
    # A 10 x 10 m region at 5 cm is tiled (issue 19 §5): 41,210 weights, 577 per tile.
    large = {"x_min_m": 0.0, "x_max_m": 10.0, "y_min_m": 0.0, "y_max_m": 10.0}
    tiled = _with_bhm({"hinge_spacing_m": 0.05, "region": large})
    tiled["run"]["evaluation_spacing_m"] = 0.01  # the core scores at most 4 M grid points
    assert validate_mapping(tiled)
    fine = _with_bhm({"hinge_spacing_m": 0.0125, "region": large})
    fine["run"]["evaluation_spacing_m"] = 0.01
    with pytest.raises(ExperimentError, match=r"tiles of 1.25e\+04 weights"):
        validate_mapping(fine)


def test_infinite_and_huge_fields_are_refused() -> None:
    for field, value in (("interaction_radius_m", float("inf")), ("tolerance", 1e300)):
        with pytest.raises(ExperimentError) as caught:
            validate_mapping(_with_bhm({field: value}))
        assert [i.path for i in caught.value.issues] == [f"maps[1].config.{field}"]
