"""Score a map against the scene: centroid error and outline distances (Table 3.2)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._scene import Scene
from .geometry import blob_centroid, directed_hausdorff_both, main_outline, sample_grid
from .kinds import Map, MovementResult, Region

__all__ = ["evaluate_map", "save_outline_figure"]


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
        "_outline": None,  # popped by the caller: the estimated outline, for the figure
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
    out["_outline"] = outline
    if outline is not None:
        est_to_true, true_to_est = directed_hausdorff_both(outline, truth.outline(512))
        out["hausdorff_est_to_true_m"] = est_to_true
        out["hausdorff_true_to_est_m"] = true_to_est
    return out


def save_outline_figure(
    path: Path,
    region: Region,
    scene: Scene,
    movements: Sequence[MovementResult],
    outline: NDArray[np.float64] | None,
    centroid: Sequence[float] | None,
    level: float,
) -> bool:
    """Draw the estimated outline over the true one with the movement paths (Figs. 3.5, 3.7).

    Returns False when matplotlib is not installed (figures are optional).
    """
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return False
    fig = Figure(figsize=(7.5, 5.2))
    ax = fig.add_subplot()
    ax.add_patch(_rectangle(region))
    for index, obj in enumerate(scene.objects):
        ring = np.vstack([obj.outline(256), obj.outline(256)[:1]])
        ax.plot(ring[:, 0], ring[:, 1], color="tab:green", lw=2, label="true outline" if not index else None)
    for result in movements:
        m = result.movement
        end = result.final_state.position_m if result.final_state is not None else m.end_m
        colour = "tab:blue" if m.phase == "phase1" else "tab:orange"
        ax.annotate("", xy=end, xytext=m.start_m,
                    arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.2})
        if result.interacted:
            ax.plot(*end, "x", color="tab:red", ms=8, mew=2)
    if outline is not None:
        ring = np.vstack([outline, outline[:1]])
        ax.plot(ring[:, 0], ring[:, 1], "k--", lw=1.5, label=f"estimated outline (p = {level:g})")
    if centroid is not None:
        ax.plot(*centroid, "k+", ms=12, mew=2, label="estimated centroid")
    ax.plot([], [], "x", color="tab:red", label="interaction (movement halted)")
    ax.set(xlim=(region.x_min_m - 0.02, region.x_max_m + 0.02),
           ylim=(region.y_min_m - 0.02, region.y_max_m + 0.02), aspect="equal",
           xlabel="x (m)", ylabel="y (m)",
           title=f"{len(movements)} exploratory movements and the estimated outline")
    ax.legend(loc="upper right", fontsize=7)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return True


def _rectangle(region: Region) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle((region.x_min_m, region.y_min_m), *region.size_m, fill=False, color="0.3")
