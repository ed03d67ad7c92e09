"""Benchmark suites of hapticframe: ``hapticframe bench search`` (dissertation Table 3.2).

The suite runs the closed-loop haptic search of Jia (2022), section 3.5.2, with the
bundled simulator, classifier, sensor model, maps and planners, and reports it beside the
thesis's figures. Runner modules load on first use, so importing this package stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ._aggregate import aggregate_trials, trial_figures
    from ._placements import Placement, draw_placements
    from ._search import run_search, run_suite
    from ._template import search_experiment

__all__ = [
    "Placement",
    "aggregate_trials",
    "draw_placements",
    "run_search",
    "run_suite",
    "search_experiment",
    "trial_figures",
]

_HOMES = {
    "Placement": "._placements",
    "draw_placements": "._placements",
    "aggregate_trials": "._aggregate",
    "trial_figures": "._aggregate",
    "run_search": "._search",
    "run_suite": "._search",
    "search_experiment": "._template",
}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(home, __name__), name)
