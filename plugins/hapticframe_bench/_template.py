"""The haptic-search experiment of the dissertation's simulation study, as a mapping.

One trial of Table 3.2 (Jia 2022, section 3.5.2): a simulated sandbox robot rakes a
fingertip through a 75 x 50 cm region holding one buried object; a force/force-rate
classifier detects granular jamming, the failure-zone kernel turns each detection into
occupancy observations, and a Bayesian Hilbert map (with an occupancy grid beside it for
comparison) feeds the planner. Every component keeps its plugin's defaults: those are
where the thesis's parameters live (Table 3.1), so tuning happens in the plugins and this
template only wires them together.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "EVALUATION_MAP",
    "PLANNER_TYPES",
    "REGION_HEIGHT_M",
    "REGION_WIDTH_M",
    "THESIS_CONFIGS",
    "search_experiment",
    "thesis_experiment",
]

#: The thesis's search area (section 3.5.1): 75 x 50 cm.
REGION_WIDTH_M = 0.75
REGION_HEIGHT_M = 0.50

#: The planner of the thesis and the exhaustive baseline it is compared with.
PLANNER_TYPES = ("two-phase-coverage", "coverage")

#: The map the core scores against the scene (the planner's map).
EVALUATION_MAP = "bhm"

#: The dissertation's own parameters (Table 3.1), by component id of
#: :func:`search_experiment`, where the bundled defaults were tuned on our sandbox instead.
#: ``examples/search-thesis.yaml`` holds the same configs (a test keeps them equal).
THESIS_CONFIGS: dict[str, dict[str, Any]] = {
    # Eqs. 3.2-3.4 as printed: sector kernels, the empirical gamma_r and eta schedules,
    # every observation of weight 1.
    "failure-zone": {
        "schedule": "empirical",
        "mixture": "one-hot",
        "empirical_gamma_scale_cm2": 72.0,
        "empirical_gamma_ratio": 0.82,
        "empirical_eta_base_deg": 50.0,
        "empirical_eta_step_deg": 7.0,
        "free_range_scale": 1.0,
        "free_gamma_scale": 1.0,
        "jamming_shape": "sector",
        "jamming_inner_scale": 0.0,
        "jamming_range_scale": 1.0,
        "jamming_angle_scale": 1.0,
        "interaction_weight": 1.0,
        "first_pair_weight": 1.0,
    },
    # Hinges every 5 cm; gamma_m = 1/(2 l^2) of 0.1 cm^-2 (free) and 0.04 cm^-2 (interaction).
    EVALUATION_MAP: {
        "hinge_spacing_m": 0.05,
        "region_dependent_smoothing": True,
        "length_scale_free_m": 0.022360679774997897,
        "length_scale_interaction_m": 0.035355339059327376,
    },
    # Eq. 3.9's w = 1, 0.5, -1; the lambda = 10 % stop rule; random sweep angles at least
    # 30 degrees apart; phase 2 from the whole region, shrinking by 25 %; binary phase 1.
    "planner": {
        "occupancy_weight": 1.0,
        "uncertainty_weight": 0.5,
        "distance_weight": -1.0,
        "stop_rule": "uncertain-area",
        "stop_fraction": 0.10,
        "sweep_rule": "random",
        "min_sweep_separation_deg": 30.0,
        "region_shrink": 0.25,
        "phase2_region_size_m": None,
        "phase1_order": "binary",
    },
}


def search_experiment(
    scene_objects: Sequence[Mapping[str, Any]],
    planner_type: str,
    seed: int,
    name: str,
) -> dict[str, Any]:
    """The experiment of one haptic-search trial, ready for ``hapticframe.validate_mapping``.

    Parameters
    ----------
    scene_objects : sequence of mapping
        Buried objects as scene data, e.g. ``{"shape": "circle", "center_m": [0.3, 0.2],
        "radius_m": 0.04}`` (see :class:`hapticframe.Circle` and :class:`hapticframe.Ellipse`).
    planner_type : str
        ``"two-phase-coverage"`` (the thesis's strategy) or ``"coverage"`` (the baseline);
        any installed planner type is accepted and checked on validation.
    seed : int
        Seeds every component's random generator (sensor noise, the simulator's drag
        fluctuations, the map's Monte-Carlo samples).
    name : str
        Name of the experiment (recorded in ``run.json``).

    Returns
    -------
    dict
        A schema-version-1 experiment: robot ``arm`` (sandbox), sensor ``wrist``
        (sandbox-force), classifier ``jamming`` (force-rate-jamming), sensor model
        ``failure-zone`` (failure-zone-kernel), maps ``grid`` (occupancy-grid) and ``bhm``
        (bayesian-hilbert-map), and planner ``planner`` reading ``bhm``; the run scores
        ``bhm``.
    """
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    if not isinstance(planner_type, str) or not planner_type:
        raise ValueError(f"planner_type must be a plugin name, got {planner_type!r}")
    return {
        "schema_version": 1,
        "name": name,
        "description": "Haptic search for one buried object (Jia 2022, section 3.5.2).",
        "seed": seed,
        "scene": {
            "region": {
                "x_min_m": 0.0,
                "x_max_m": REGION_WIDTH_M,
                "y_min_m": 0.0,
                "y_max_m": REGION_HEIGHT_M,
            },
            "objects": [dict(obj) for obj in scene_objects],
        },
        "robots": [{"id": "arm", "type": "sandbox"}],
        "sensors": [{"id": "wrist", "type": "sandbox-force", "inputs": ["arm"]}],
        "classifiers": [{"id": "jamming", "type": "force-rate-jamming", "inputs": ["wrist"]}],
        "sensor_models": [
            {"id": "failure-zone", "type": "failure-zone-kernel", "inputs": ["jamming", "arm"]}
        ],
        "maps": [
            {"id": "grid", "type": "occupancy-grid", "inputs": ["failure-zone"]},
            {"id": EVALUATION_MAP, "type": "bayesian-hilbert-map", "inputs": ["failure-zone"]},
        ],
        "planners": [{"id": "planner", "type": planner_type, "inputs": [EVALUATION_MAP]}],
        "run": {"evaluation_map": EVALUATION_MAP},
    }


def thesis_experiment(experiment: Mapping[str, Any]) -> dict[str, Any]:
    """``experiment`` (from :func:`search_experiment` with the two-phase planner) with the
    dissertation's Table 3.1 configuration (:data:`THESIS_CONFIGS`) in its components.

    Raises
    ------
    ValueError
        When the experiment lacks a component that the configuration is for.
    """
    out = dict(experiment)
    configured = set()
    for section in ("sensor_models", "maps", "planners"):
        entries = []
        for entry in out.get(section, ()):
            entry = dict(entry)
            if entry.get("id") in THESIS_CONFIGS:
                entry["config"] = {**entry.get("config", {}), **THESIS_CONFIGS[entry["id"]]}
                configured.add(entry["id"])
            entries.append(entry)
        out[section] = entries
    missing = sorted(set(THESIS_CONFIGS) - configured)
    if missing:
        raise ValueError(f"the experiment has no component {', '.join(missing)} to configure")
    return out
