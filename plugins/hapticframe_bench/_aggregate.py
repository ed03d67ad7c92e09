"""Pure statistics of the search benchmark: per-trial figures and their summaries.

Nothing here runs an experiment: :func:`trial_figures` reads one run's metrics (as the core
and the plugins write them to ``metrics.json``) and :func:`aggregate_trials` summarises a
group of trials of one shape and one planner in the form of Table 3.2.

Conventions
-----------
* The symmetric Hausdorff distance of a trial is the larger of the two directed distances
  (estimated outline to true outline and back); the thesis reports a "directed Hausdorff
  distance" without naming the direction, so both directions are summarised as well.
* Standard deviations are population standard deviations (``ddof=0``, numpy's default):
  the thesis does not say which it used, and this one is defined for a single trial.
* Centroid and outline figures exist only for trials where the object was found; they are
  summarised over those trials, and ``n`` says how many there were. Movement counts,
  interactions and forces are summarised over every completed trial.
* A trial whose run failed contributes to ``failed`` and to nothing else.
* A scene of several objects (issue 19) also has ``objects_total``, ``objects_found``,
  ``objects_missed`` and ``false_blobs`` per trial (the core's Hungarian matching); its
  aggregate sums them under ``objects``. ``object_found`` is then "every object found" and
  the lengths are the worst found object's.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "COUNT_FIGURES",
    "LENGTH_FIGURES",
    "OBJECT_COUNTS",
    "aggregate_trials",
    "mean_std",
    "root_mean_square",
    "trial_figures",
]

#: Figures in metres, summarised over the trials that found the object.
LENGTH_FIGURES = (
    "centroid_error_m",
    "hausdorff_m",
    "hausdorff_est_to_true_m",
    "hausdorff_true_to_est_m",
)
#: Figures summarised over every completed trial.
COUNT_FIGURES = (
    "ems_phase1",
    "ems_phase2",
    "movements",
    "object_interactions",
    "max_force_n",
    "wall_time_s",
)
#: Per-object counts of a multi-object scene's metrics, summed over trials.
OBJECT_COUNTS = ("objects_total", "objects_found", "objects_missed", "false_blobs")
#: Figures that are counts.
_INTEGER_FIGURES = frozenset({"ems_phase1", "ems_phase2", "movements", "object_interactions"})


def _finite(value: Any) -> float | None:
    """``value`` as a float when it is a finite real number, else None."""
    if value is None or isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _numbers(values: Iterable[Any]) -> list[float]:
    return [v for v in (_finite(x) for x in values) if v is not None]


def mean_std(values: Iterable[Any]) -> dict[str, Any]:
    """Mean and population standard deviation of the finite numbers in ``values``.

    Returns
    -------
    dict
        ``{"mean": float | None, "std": float | None, "n": int}``; None (never NaN)
        when there is no finite number.
    """
    numbers = _numbers(values)
    if not numbers:
        return {"mean": None, "std": None, "n": 0}
    array = np.asarray(numbers, dtype=np.float64)
    # Subtracting the mean first keeps the std exact for large, nearly equal values.
    mean = float(np.mean(array))
    std = float(np.sqrt(np.mean((array - mean) ** 2)))
    return {"mean": mean, "std": std, "n": len(numbers)}


def root_mean_square(values: Iterable[Any]) -> float | None:
    """Root mean square of the finite numbers in ``values`` (None when there are none).

    Scaled by the largest magnitude first so huge or tiny values neither overflow nor
    underflow when squared.
    """
    numbers = _numbers(values)
    if not numbers:
        return None
    array = np.abs(np.asarray(numbers, dtype=np.float64))
    scale = float(array.max())
    if scale == 0.0:
        return 0.0
    return scale * float(np.sqrt(np.mean((array / scale) ** 2)))


def trial_figures(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """The figures of one completed trial, read from its run's metrics.

    Parameters
    ----------
    metrics : mapping
        A run's metrics (``metrics.json``): the core's ``object_found``,
        ``centroid_error_m``, ``hausdorff_est_to_true_m``, ``hausdorff_true_to_est_m``,
        ``movements`` and ``wall_time_s``, the planners' ``ems_phase1`` and ``ems_phase2``
        and the sandbox robot's ``max_force_n`` and ``object_interactions``. Missing or
        non-finite entries become None.

    Returns
    -------
    dict
        ``object_found`` (bool), ``hausdorff_m`` (the symmetric distance, None unless
        both directions are known) and every figure of :data:`LENGTH_FIGURES` and
        :data:`COUNT_FIGURES`.
    """
    found = bool(metrics.get("object_found", False))
    out: dict[str, Any] = {"object_found": found}
    for key in LENGTH_FIGURES:
        if key != "hausdorff_m":
            out[key] = _finite(metrics.get(key)) if found else None
    directed = (out["hausdorff_est_to_true_m"], out["hausdorff_true_to_est_m"])
    out["hausdorff_m"] = None if None in directed else max(directed)
    for key in COUNT_FIGURES:
        value = _finite(metrics.get(key))
        # Counts stay ints in search.json (readable), any other number stays a float.
        if value is not None and key in _INTEGER_FIGURES and value.is_integer():
            out[key] = int(value)
        else:
            out[key] = value
    if "objects_total" in metrics:  # only a multi-object scene's metrics have these
        for key in OBJECT_COUNTS:
            value = _finite(metrics.get(key))
            out[key] = None if value is None else int(value)
    return out


def aggregate_trials(
    trials: Sequence[Mapping[str, Any]], force_limit_n: float | None = None
) -> dict[str, Any]:
    """Summarise the trials of one shape and one planner.

    Parameters
    ----------
    trials : sequence of mapping
        One record per trial: ``status`` ("ok" or "failed"), ``figures`` (the output of
        :func:`trial_figures`, for completed trials) and, for failed ones, ``error`` and
        ``index``.
    force_limit_n : float or None
        Trials whose ``max_force_n`` exceeds this are counted in ``force_limit_exceeded``
        (None counts nothing and reports None).

    Returns
    -------
    dict
        ``trials``, ``completed``, ``failed``, ``failures`` (index and error of each
        failed trial), ``found`` and ``found_fraction`` (over completed trials; None when
        none completed), ``centroid_rmse_m`` (a number, or None when the object was never
        found), ``{"mean", "std", "n"}`` for every figure of :data:`LENGTH_FIGURES` and
        :data:`COUNT_FIGURES`, ``force_limit_n`` and ``force_limit_exceeded``; for a
        multi-object scene also ``objects`` (:data:`OBJECT_COUNTS` summed over trials).
    """
    completed = [t for t in trials if t.get("status") == "ok"]
    failed = [t for t in trials if t.get("status") != "ok"]
    figures = [t["figures"] for t in completed]
    found = [f for f in figures if f.get("object_found")]
    out: dict[str, Any] = {
        "trials": len(trials),
        "completed": len(completed),
        "failed": len(failed),
        "failures": [
            {"index": t.get("index"), "error": str(t.get("error", ""))} for t in failed
        ],
        "found": len(found),
        "found_fraction": len(found) / len(completed) if completed else None,
        "centroid_rmse_m": root_mean_square(f.get("centroid_error_m") for f in found),
    }
    for key in LENGTH_FIGURES:
        out[key] = mean_std(f.get(key) for f in found)
    for key in COUNT_FIGURES:
        out[key] = mean_std(f.get(key) for f in figures)
    if any("objects_total" in f for f in figures):
        out["objects"] = {key: sum(int(f.get(key) or 0) for f in figures)
                          for key in OBJECT_COUNTS}
    limit = _finite(force_limit_n)
    out["force_limit_n"] = limit
    if limit is None:
        out["force_limit_exceeded"] = None
    else:
        forces = (_finite(f.get("max_force_n")) for f in figures)
        out["force_limit_exceeded"] = sum(1 for v in forces if v is not None and v > limit)
    return out
