"""Score a map against the scene: centroid error and outline distances (Table 3.2)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ._scene import Scene
from .geometry import blob_centroid, directed_hausdorff_both, main_outline, sample_grid
from .kinds import Map

__all__ = ["evaluate_map"]


def evaluate_map(
    the_map: Map,
    scene: Scene,
    *,
    level: float = 0.6,
    spacing_m: float = 0.0025,
    near_m: ArrayLike | None = None,
) -> dict[str, Any]:
    """Compare the map's estimated object with the nearest true object.

    The estimate is the connected region where the occupancy mean reaches ``level``: the
    one closest to ``near_m`` (where the robot met the object) when given, else the one
    holding the most occupancy. Its centroid and its ``level`` curve are compared with the
    true object's centroid and outline. Distances are directed Hausdorff distances in both
    directions. When nothing reaches ``level`` the object counts as not found and the
    distances are None.
    """
    region = the_map.region
    xs, ys, points = sample_grid(
        (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m), spacing_m
    )
    mean = the_map.query(points).mean.reshape(len(ys), len(xs))
    out: dict[str, Any] = {
        "object_found": False,
        "centroid_error_m": None,
        "estimated_centroid_m": None,
        "hausdorff_est_to_true_m": None,
        "hausdorff_true_to_est_m": None,
    }
    centroid = blob_centroid(xs, ys, mean, level, near_m=near_m)
    if centroid is None:
        return out
    truths = [obj.centroid_m for obj in scene.objects]
    nearest = int(np.argmin([np.linalg.norm(centroid - t) for t in truths]))
    truth = scene.objects[nearest]
    out["object_found"] = True
    out["estimated_centroid_m"] = centroid.tolist()
    out["centroid_error_m"] = float(np.linalg.norm(centroid - truth.centroid_m))
    outline = main_outline(xs, ys, mean, level, near_m=centroid)
    if outline is not None:
        est_to_true, true_to_est = directed_hausdorff_both(outline, truth.outline(512))
        out["hausdorff_est_to_true_m"] = est_to_true
        out["hausdorff_true_to_est_m"] = true_to_est
    return out
