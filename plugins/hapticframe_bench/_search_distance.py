"""``hapticframe bench search-distance``: Table 3.2's protocol with the distance estimate.

Every placement of :func:`~hapticframe_bench._search.run_suite` is searched by the
two-phase planner twice: through the failure-zone kernel (role ``search``: the sandbox's
2-D force, ``force-rate-jamming``, ``failure-zone-kernel``) and through the distance
estimate (role ``distance-estimate``: ``sandbox-taxels``, the sandbox force read as a real
rake's 4 taxels by the measurement model fitted to the real trials, the ``raking-estimator``
trained here on sandbox approaches, and the ``distance-estimate`` sensor model).

Before the trials the estimator is trained on ``sandbox-taxels`` approaches (60, or 20
with ``--quick``) at an 8 cm circle and a 9 x 5 cm ellipse elsewhere in a sandbox of their
own, and saved in ``OUT/estimator/``. Reports ``search-distance.json`` and
``search-distance.md`` (movements, object interactions, centroid RMSE, Hausdorff
distances, found rate per shape and sensor model).
"""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe import BenchOptions, Circle, Ellipse, Scene, atomic_write
from hapticframe.kinds import BuildContext

from ._report import format_mean_std
from ._search import SEARCH_PLANNER, run_suite

__all__ = ["DISTANCE_ROLE", "distance_experiment", "run_search_distance",
           "train_sandbox_estimator"]

DISTANCE_ROLE = "distance-estimate"
#: The estimate within which the estimator says "near" (the halt): 20 mm halts too far
#: out for the map to find the object (examples/search-ellipse-distance.yaml).
NEAR_MM = 10.0
TRAINING_APPROACHES = 60
QUICK_TRAINING_APPROACHES = 20


def train_sandbox_estimator(out_dir: Path, approaches: int, seed: int,
                            epochs: int = 15) -> dict[str, Any]:
    """Train a ``raking-estimator`` on ``sandbox-taxels`` approaches; save it in
    ``out_dir``. Returns the training report with ``train_wall_s``."""
    from hapticframe_raking import RakingEstimator, RakingEstimatorConfig
    from hapticframe_sandbox import (
        SandboxRobot,
        SandboxRobotConfig,
        SandboxTaxelSensor,
        SandboxTaxelSensorConfig,
    )

    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    scene = Scene(objects=[
        Circle(center_m=(0.2, 0.25), radius_m=0.04),
        Ellipse(center_m=(0.55, 0.25), semi_axes_m=(0.045, 0.025), orientation_deg=35)])
    robot = SandboxRobot(SandboxRobotConfig(), BuildContext(
        id="arm", rng=np.random.default_rng(rng.integers(2**32)), scene=scene))
    sensor = SandboxTaxelSensor(
        SandboxTaxelSensorConfig(approach_trials=approaches),
        BuildContext(id="taxels", rng=np.random.default_rng(rng.integers(2**32)),
                     inputs={"arm": robot}, scene=scene))
    batches = list(sensor.iter_recordings())
    estimator = RakingEstimator(RakingEstimatorConfig(epochs=epochs), BuildContext(
        id="estimator", rng=np.random.default_rng(rng.integers(2**32))))
    estimator.fit(batches, [np.zeros(len(b)) for b in batches])
    out_dir.mkdir(parents=True, exist_ok=True)
    estimator.save(out_dir)
    report = dict(estimator.training_report())
    report.pop("losses", None)
    return report | {"approaches": approaches, "train_wall_s": time.perf_counter() - started}


def distance_experiment(data: dict[str, Any], model_dir: str) -> dict[str, Any]:
    """A search trial's experiment with the distance chain in place of the failure zone."""
    out = copy.deepcopy(data)
    out["sensors"] = [{"id": "taxels", "type": "sandbox-taxels", "inputs": ["arm"]}]
    out["classifiers"] = [{"id": "estimator", "type": "raking-estimator",
                           "inputs": ["taxels"],
                           "config": {"near_mm": NEAR_MM, "model_dir": model_dir}}]
    out["sensor_models"] = [{"id": "distance", "type": "distance-estimate",
                             "inputs": ["estimator", "arm"]}]
    for entry in out["maps"]:
        entry["inputs"] = ["distance"]
    for entry in out["planners"]:
        # The estimator's classes are far / near: a movement that ends "far" did not meet
        # the object (with the planner's default, only "free" is free, every movement
        # counted as an interaction and phase 1 always ended after its first line).
        entry["config"] = {**entry.get("config", {}), "free_class_names": ["far"]}
    out["name"] = str(out.get("name", "search")) + "-distance"
    return out


def _rows(summary: dict[str, Any]) -> list[str]:
    lines = ["| shape | sensor model | EMs phase 1 | EMs phase 2 | movements | object "
             "interactions | centroid RMSE | Hausdorff est→true | Hausdorff true→est | found |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for shape in summary["shapes"]:
        for label, group in (("failure-zone-kernel", summary[shape]),
                             ("distance-estimate", summary[DISTANCE_ROLE][shape])):
            rmse = group.get("centroid_rmse_m")
            lines.append("| " + " | ".join([
                shape, label, format_mean_std(group.get("ems_phase1")),
                format_mean_std(group.get("ems_phase2")),
                format_mean_std(group.get("movements")),
                format_mean_std(group.get("object_interactions")),
                "–" if rmse is None else f"{rmse * 100:.1f} cm",
                format_mean_std(group.get("hausdorff_est_to_true_m"), scale=100, unit="cm"),
                format_mean_std(group.get("hausdorff_true_to_est_m"), scale=100, unit="cm"),
                f"{group.get('found', 0)}/{group.get('completed', 0)}"]) + " |")
    return lines


def run_search_distance(options: BenchOptions) -> dict[str, Any]:
    """Train the estimator on sandbox approaches, then run both sensor models on every
    placement (module docstring). Options as for ``bench search``."""
    out_dir = Path(options.out_dir)
    model_dir = (out_dir / "estimator").resolve()
    approaches = QUICK_TRAINING_APPROACHES if options.quick else TRAINING_APPROACHES
    options.echo(f"training the raking estimator on {approaches} sandbox-taxels approaches")
    training = train_sandbox_estimator(model_dir, approaches, options.seed,
                                       epochs=5 if options.quick else 15)
    options.echo(f"trained in {training['train_wall_s']:.1f} s into {model_dir}")
    summary = run_suite(
        options, planners={"search": SEARCH_PLANNER, DISTANCE_ROLE: SEARCH_PLANNER},
        report_name="search-distance",
        role_experiments={DISTANCE_ROLE: lambda d: distance_experiment(d, str(model_dir))})
    summary["estimator_training"] = training
    summary["command"] = str(summary["command"]).replace("bench search ",
                                                         "bench search-distance ", 1)
    lines = [f"# Search with the distance estimate ({summary['trials']} placements per shape)",
             "", *_rows(summary), "",
             f"Estimator: trained on {approaches} sandbox-taxels approaches in "
             f"{training['train_wall_s']:.1f} s; near (the halt) below {NEAR_MM:g} mm. "
             f"Command: `{summary['command']}`; whole command {summary['wall_time_s']:.0f} s.",
             ""]
    atomic_write(out_dir / "search-distance.md", "\n".join(lines))
    import json

    atomic_write(out_dir / "search-distance.json",
                 json.dumps(summary, indent=2, allow_nan=False) + "\n")
    return summary
