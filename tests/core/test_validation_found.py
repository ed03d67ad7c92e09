"""Issue 16 §1: `object_found` means a blob near a true object, within a stated distance.

With ``noise_std_n: 5`` a run once reported found with a 0.31 m centroid error: any blob
over the outline level counted. Found now means the estimated centroid lies within
``run.found_within_m`` of the nearest true object's centroid (default: that object's reach,
its radius for a circle); ``metrics.json`` records the distance used.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import ArrayLike

from hapticframe import RunSettings, Scene
from hapticframe.kinds import MapEstimate, Region
from hapticframe.run._evaluate import evaluate_map


class BlobMap:
    """A map that is occupied (1.0) in one disc, free elsewhere."""

    region = Region(0.0, 0.75, 0.0, 0.5)

    def __init__(self, centre: tuple[float, float], radius_m: float = 0.03) -> None:
        self.centre = np.asarray(centre)
        self.radius_m = radius_m

    def query(self, points_m: ArrayLike) -> MapEstimate:
        p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        inside = np.hypot(*(p - self.centre).T) <= self.radius_m
        mean = np.where(inside, 1.0, 0.0)
        return MapEstimate(mean, np.zeros(len(p)))


SCENE = Scene.model_validate(
    {"objects": [{"shape": "circle", "center_m": [0.30, 0.25], "radius_m": 0.04}]}
)


def _score(blob: tuple[float, float], within: float | None = None) -> dict[str, object]:
    return evaluate_map(BlobMap(blob), SCENE, spacing_m=0.005,  # type: ignore[arg-type]
                        found_within_m=within).metrics


def test_a_blob_far_from_every_object_is_not_found() -> None:
    out = _score((0.61, 0.25))
    assert out["object_found"] is False
    assert out["centroid_error_m"] == pytest.approx(0.31, abs=0.005)
    assert out["found_within_m"] == pytest.approx(0.04)  # the circle's radius


def test_a_blob_on_the_object_is_found() -> None:
    out = _score((0.31, 0.26))
    assert out["object_found"] is True and out["found_within_m"] == pytest.approx(0.04)


def test_a_stated_distance_is_used_and_reported() -> None:
    out = _score((0.61, 0.25), within=0.5)
    assert out["object_found"] is True and out["found_within_m"] == 0.5
    assert _score((0.36, 0.25), within=0.02)["object_found"] is False


def test_no_blob_is_not_found() -> None:
    score = evaluate_map(BlobMap((5.0, 5.0)), SCENE, spacing_m=0.005)  # type: ignore[arg-type]
    out = score.metrics
    assert out["object_found"] is False and out["centroid_error_m"] is None
    assert score.outlines == () and score.centroids == ()


def test_the_run_setting_is_bounded() -> None:
    assert RunSettings().found_within_m is None
    for bad in (0.0, -1.0, float("inf"), float("nan"), 11.0):
        with pytest.raises(ValueError):
            RunSettings(found_within_m=bad)
