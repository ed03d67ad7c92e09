"""Benchmark suites of hapticframe (``hapticframe bench NAME``), one module per study.

- ``search`` (:mod:`._search`): the closed-loop haptic search of Jia (2022), section 3.5.2,
  Table 3.2, with the bundled simulator, classifier, sensor model, maps and planners;
- ``perception`` (:mod:`._perception`): Tables 2.2, 2.3, 2.4 and A.1 on the synthetic
  BioTac dataset, with the streaming chain's latency;
- ``search-devices`` (:mod:`._search_devices`): the same search through the emulated
  FT 300 and BNO055 and the force observer, beside the pure simulation, after calibrating
  the observer on free motions;
- ``bhm`` (:mod:`._bhm`): the Bayesian Hilbert map's timing targets;
- ``latency`` (:mod:`._latency`): the streaming feature chain and a classifier step per
  frame, and our EMD against PyEMD.

Each suite prints its targets beside its measurements with a verdict and writes the same
to its JSON and markdown. The suites use only the public API of the plugins they measure.
Runner modules load on first use, so importing this package stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe import lazy_exports

if TYPE_CHECKING:
    from ._aggregate import aggregate_trials, trial_figures
    from ._bhm import benchmark_bhm, labelled_points, roc_auc, run_bhm_bench, two_object_scene
    from ._latency import (
        compare_emd_with_pyemd,
        measure_chain_latency,
        measure_step_latency,
        measure_torch_steps,
        run_latency_bench,
        synthetic_biotac_frames,
    )
    from ._perception import run_perception
    from ._placements import Placement, draw_placements
    from ._search import run_search, run_suite
    from ._search_devices import calibrate_observer, chain_experiment, run_search_devices
    from ._separability import linear_svm_separability
    from ._targets import Target, TargetCheck, check_targets
    from ._template import search_experiment

__all__ = [
    "Placement",
    "Target",
    "TargetCheck",
    "aggregate_trials",
    "benchmark_bhm",
    "calibrate_observer",
    "chain_experiment",
    "check_targets",
    "compare_emd_with_pyemd",
    "draw_placements",
    "labelled_points",
    "linear_svm_separability",
    "measure_chain_latency",
    "measure_step_latency",
    "measure_torch_steps",
    "roc_auc",
    "run_bhm_bench",
    "run_latency_bench",
    "run_perception",
    "run_search",
    "run_search_devices",
    "run_suite",
    "search_experiment",
    "synthetic_biotac_frames",
    "trial_figures",
    "two_object_scene",
]

_HOMES = {
    "Placement": "._placements",
    "draw_placements": "._placements",
    "aggregate_trials": "._aggregate",
    "trial_figures": "._aggregate",
    "run_search": "._search",
    "run_suite": "._search",
    "calibrate_observer": "._search_devices",
    "chain_experiment": "._search_devices",
    "run_search_devices": "._search_devices",
    "search_experiment": "._template",
    "run_perception": "._perception",
    "benchmark_bhm": "._bhm",
    "labelled_points": "._bhm",
    "roc_auc": "._bhm",
    "run_bhm_bench": "._bhm",
    "two_object_scene": "._bhm",
    "compare_emd_with_pyemd": "._latency",
    "measure_chain_latency": "._latency",
    "measure_step_latency": "._latency",
    "measure_torch_steps": "._latency",
    "run_latency_bench": "._latency",
    "synthetic_biotac_frames": "._latency",
    "linear_svm_separability": "._separability",
    "Target": "._targets",
    "TargetCheck": "._targets",
    "check_targets": "._targets",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
