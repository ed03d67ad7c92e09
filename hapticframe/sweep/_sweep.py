"""``hapticframe sweep``: what accuracy a setting buys, and what it costs.

A sweep varies config fields (``--vary bhm.hinge_spacing_m=0.025,0.05,0.1``, or every knob
the experiment's plugins declare with ``--declared``) and runs each *point* over ``N``
seeded trials (trial ``i`` runs with ``seed + i``). By default one knob changes at a time
from the file's values (plus the baseline point, the file as it is); ``grid=True`` runs
every combination. Every trial is a :func:`~hapticframe.run_experiment` in a worker, with
figures and the recording off, into ``DIR/points/<point>/trial-<i>/``; its ``run.json``
records the point's values as overrides (``--set``). With the process pool, each worker
starts with one untimed run of the first point, so that import and first-call costs fall
on no point. The workers start from a fork server (where the platform has one), never
forked from this process: a parent that has run torch's OpenMP threads would leave a
forked child waiting for ever on threads it does not have, as the perception sweep of
issue 18 did.

Each trial is measured for accuracy (every scalar of ``metrics.json``: for a search the
object found, centroid error, Hausdorff distances, movements and EMs, object interactions,
largest force; for perception the balanced accuracies and onset errors; for a map its
AUC and log loss, where the run reports them) and for cost (wall and CPU time of the run
and per robot step, peak resident memory of the worker while it ran).

Outputs in ``DIR``: ``sweep.json`` (every trial and point, and the machine's load),
``sweep.md`` (a table per knob, saying where a knob changed no accuracy metric, and the
Pareto fronts over all points: the accuracy cost, :func:`accuracy_measure`, against mean
wall time and against mean CPU time per run; a search point that found the object in
fewer trials than the best is kept off them) and ``pareto.png`` (every point against wall
time, the front highlighted).

A point that fails (a value validation refuses, an exception, a non-finite metric, a
trial past ``timeout_s``) is a row saying so, never a crash: sweeping to the extremes is
how numerical trouble shows. Trials run through a :class:`concurrent.futures.Executor`
from :func:`make_executor`: a local process pool, or a Dask cluster (``dask``; the
optional ``distributed`` extra). Results do not depend on the executor: every trial has
its own seed.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import platform
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from hapticframe._atomic import OutputError, atomic_write
from hapticframe._config._load import load_file
from hapticframe._config._overrides import (
    Override,
    apply_overrides,
    parse_overrides,
    parse_value_list,
    resolve_path,
    validate_with_overrides,
)
from hapticframe._errors import ExperimentError, UsageError, shown
from hapticframe.run._results import OutputDir
from hapticframe.sweep._format import flow_text, format_value
from hapticframe.sweep._sweep_trials import (
    COST_KEYS,
    EXECUTORS,
    TrialTask,
    _gather,
    _mark_nan_against_baseline,
    make_executor,
    run_trial,
)

__all__ = [
    "EXECUTORS",
    "Point",
    "TrialTask",
    "Vary",
    "accuracy_measure",
    "make_executor",
    "pareto_front",
    "parse_vary",
    "plan_points",
    "run_sweep",
    "run_trial",
]

# --- what to vary --------------------------------------------------------------------------


@dataclass(frozen=True)
class Vary:
    """One knob of a sweep: an override path and the values to try."""

    path: str
    values: tuple[Any, ...]
    trades: str = ""


def parse_vary(text: str) -> Vary:
    """``--vary PATH=V1,V2,...`` (each value YAML; a list value in brackets)."""
    where = f"--vary {shown(text)}"
    path, sep, values = text.partition("=")
    if not sep or not path.strip():
        raise UsageError(f"{where}: write PATH=V1,V2,..., e.g. bhm.hinge_spacing_m=0.025,0.05")
    return Vary(path.strip(), tuple(parse_value_list(values, where)))


@dataclass(frozen=True)
class Point:
    """One setting of a sweep: the values it changes (none for the baseline)."""

    label: str
    values: tuple[tuple[str, Any], ...] = ()

    @property
    def is_baseline(self) -> bool:
        return not self.values


def _label(values: Sequence[tuple[str, Any]]) -> str:
    return ", ".join(f"{path}={flow_text(value)}" for path, value in values) or "baseline"


def plan_points(varies: Sequence[Vary], baseline: Mapping[str, Any], *,
                grid: bool = False) -> list[Point]:
    """The points of a sweep, the baseline first.

    One at a time (default): each value of each knob with the others at the file's
    values; a value equal to the file's (``baseline[path]``) is the baseline point itself.
    ``grid``: every combination of the knobs' values (the baseline added when it is not
    one of them).
    """
    points = [Point("baseline")]
    seen: set[str] = {points[0].label}
    if grid:
        for combo in itertools.product(*[[(v.path, x) for x in v.values] for v in varies]):
            if all(_same(x, baseline.get(p, _MISSING)) for p, x in combo):
                continue  # the file's own setting: the baseline point
            label = _label(combo)
            if label not in seen:
                seen.add(label)
                points.append(Point(label, tuple(combo)))
        return points
    for vary in varies:
        for value in vary.values:
            if _same(value, baseline.get(vary.path, _MISSING)):
                continue
            label = _label([(vary.path, value)])
            if label not in seen:
                seen.add(label)
                points.append(Point(label, ((vary.path, value),)))
    return points


_MISSING = object()


def _same(a: Any, b: Any) -> bool:
    """``a == b`` as the config sees it: 0.05 and 0.05, 2 and 2.0; never True and 1."""
    if b is _MISSING or isinstance(a, bool) != isinstance(b, bool):
        return False
    try:
        return bool(a == b)
    except Exception:  # an exotic value: compare nothing
        return False


def _declared(experiment: Any) -> list[Vary]:
    """Every knob the experiment's components (and its run loop) declare."""
    import importlib

    try:
        pairs = importlib.import_module("hapticframe._knobs").declared_knobs(experiment)
    except ImportError:  # before the knobs module: read the specs' own declarations
        pairs = [(entry.id, knob) for entry in experiment.components
                 for knob in getattr(entry.registered.spec, "knobs", ())]
    return [Vary(f"{cid}.{knob.field}", tuple(_tidy(v) for v in knob.sweep_values()),
                 knob.trades) for cid, knob in pairs]


def _tidy(value: Any) -> Any:
    """A declared range's float to 3 significant digits (0.0171, not 0.017099759466766964):
    the labels and tables stay readable, and no knob's effect hangs on the fourth digit."""
    if isinstance(value, float) and math.isfinite(value) and value != 0.0:
        return float(f"{value:.3g}")
    return value


def _merged(varies: Sequence[Vary]) -> list[Vary]:
    """One knob per path (a path given twice, or given and declared: its values joined in
    order, the first ``trades`` kept)."""
    merged: dict[str, Vary] = {}
    for vary in varies:
        known = merged.get(vary.path)
        if known is None:
            merged[vary.path] = vary
            continue
        values = list(known.values)
        values += [v for v in vary.values if not any(_same(v, w) for w in values)]
        merged[vary.path] = Vary(vary.path, tuple(values), known.trades or vary.trades)
    return list(merged.values())


def _baseline_value(experiment: Any, data: Any, path: str) -> Any:
    """The value the validated experiment holds at an override ``path`` (its default when
    the file says nothing), or :data:`_MISSING`."""
    node: Any = experiment.resolved_config()
    for part in resolve_path(data, Override(path, None, path)):
        if isinstance(part, int) and isinstance(node, list) and part < len(node):
            node = node[part]
        elif isinstance(part, str) and isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return _MISSING
    return node


# --- aggregation -----------------------------------------------------------------------------


#: Search metrics shown in the tables, in this order, when a run reports them.
def accuracy_measure(keys: Sequence[str]) -> tuple[str, str, Callable[[float], float]] | None:
    """The accuracy cost a sweep's Pareto front uses, from the metrics its runs report:
    (metric, description, metric mean to cost; lower cost is better).

    A classifier's balanced accuracy comes first: a perception run that also maps reports
    a centroid error too, but what its knobs trade is the contact-state accuracy (the
    example's belief-map centroid is within a millimetre whatever the classifier does).
    """
    keys = list(keys)
    for key in keys:
        if key.endswith("_balanced_accuracy"):
            return key, f"1 - mean {key}", lambda v: 1.0 - v
    if "centroid_error_m" in keys:
        return "centroid_error_m", "mean centroid error (m)", float
    for key in keys:
        if "log_loss" in key:
            return key, f"mean {key}", float
    for key in keys:
        if key.endswith("auc") or "_auc" in key:
            return key, f"1 - mean {key}", lambda v: 1.0 - v
    return None


def _mean(values: Sequence[Any]) -> float | None:
    finite = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    return sum(finite) / len(finite) if finite else None


def _std(values: Sequence[Any]) -> float | None:
    finite = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    if len(finite) < 2:
        return None
    m = sum(finite) / len(finite)
    return math.sqrt(sum((v - m) ** 2 for v in finite) / (len(finite) - 1))


def _summarise_point(point: Point, rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    keys = sorted({k for r in ok for k in r["metrics"]})
    means = {k: _mean([r["metrics"].get(k) for r in ok]) for k in keys}
    stds = {k: _std([r["metrics"].get(k) for r in ok]) for k in keys}
    cost = {k: _mean([r.get(k) for r in ok]) for k in COST_KEYS}
    cost_std = {k: _std([r.get(k) for r in ok]) for k in COST_KEYS}
    if not rows:
        status = "invalid"
    elif not failed:
        status = "ok"
    else:
        kinds = sorted({r["status"] for r in failed})
        status = "/".join(kinds) if not ok else "partly " + "/".join(kinds)
    return {"label": point.label, "values": [{"path": p, "value": v} for p, v in point.values],
            "status": status, "trials": len(rows), "trials_ok": len(ok),
            "errors": sorted({str(r["error"]) for r in failed}),
            "warnings": sum(int((r.get("warnings") or {}).get("count", 0)) for r in rows),
            "warning_messages": list(dict.fromkeys(
                m for r in rows for m in (r.get("warnings") or {}).get("messages", ())))[:3],
            "metrics": means, "metrics_std": stds, "cost": cost, "cost_std": cost_std}


def pareto_front(points: Sequence[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both (time, cost), lower better;
    sorted by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front: list[int] = []
    best = math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


# --- the sweep -------------------------------------------------------------------------------


@dataclass
class SweepOptions:
    """What ``hapticframe sweep`` was asked (see :func:`run_sweep`)."""

    varies: tuple[Vary, ...] = ()
    declared: bool = False
    grid: bool = False
    trials: int = 1
    workers: int | None = None
    timeout_s: float | None = None
    executor: str = "process"
    scheduler: str | None = None
    overrides: tuple[Override, ...] = ()
    plugin_modules: tuple[str, ...] = ()
    echo: Callable[[str], None] = field(default=print)
    #: Clear an earlier sweep in ``--out`` first (only what its ``sweep.json`` lists).
    overwrite: bool = False
    min_free_bytes: int | None = None


def _point_dir(index: int) -> str:
    return f"p{index:03d}"


def run_sweep(file: str | Path, out_dir: str | Path, options: SweepOptions) -> dict[str, Any]:
    """Run a sweep of the experiment ``file`` into ``out_dir`` (see the module's notes).

    Returns
    -------
    dict
        What ``sweep.json`` holds: ``points`` (label, values, status, trials, mean and
        standard deviation of each metric, mean costs, ``front``), ``trials`` (every
        trial's row), ``knobs``, ``accuracy`` (the front's measure), ``front`` (point
        labels), the settings and the machine.

    Raises
    ------
    ExperimentError, UsageError
        The file (with the sweep's ``--set``) is invalid, nothing is varied, or a
        ``--vary`` path names nothing: before any trial runs (exit status 2).
    """
    started = time.perf_counter()
    load_before = _load_average()
    echo = options.echo
    if options.trials < 1:
        raise UsageError("--trials must be at least 1")
    if options.timeout_s is not None and not options.timeout_s > 0:
        raise UsageError("--timeout-s must be positive")
    loaded = load_file(file)
    plugin_dir = str(Path.cwd()) if options.plugin_modules else None
    base = validate_with_overrides(loaded, options.overrides,
                                   plugin_modules=options.plugin_modules, plugin_dir=plugin_dir)
    changed, _ = apply_overrides(loaded, options.overrides)
    varies = list(options.varies)
    if options.declared:
        declared = _declared(base)
        varies += declared
        if not declared:
            echo("the experiment's plugins declare no knobs")
    varies = _merged(varies)
    if not varies:
        raise UsageError("nothing to vary: give --vary PATH=V1,V2,... or --declared")
    baseline: dict[str, Any] = {}
    for vary in varies:
        baseline[vary.path] = _baseline_value(base, changed.data, vary.path)
    points = plan_points(varies, baseline, grid=options.grid)
    # Guarded as a run's --out: checked, locked for the sweep's life, cleared only with
    # --overwrite and only of what an earlier sweep listed; the trials and tables go to a
    # staging folder that moves in when the sweep ends.
    directory = OutputDir.prepare(out_dir, record="sweep.json", command="sweep",
                                  overwrite=options.overwrite,
                                  min_free=options.min_free_bytes, inputs=(file,))
    try:
        directory.begin({"experiment_file": str(file), "pid": os.getpid(),
                         "started_utc": datetime.now(timezone.utc).isoformat(
                             timespec="seconds")})
        try:
            result = _sweep(file, loaded, base, points, varies, baseline, directory.staging,
                            directory.path, options, started, load_before)
        except BaseException as exc:
            failed = {"experiment_file": str(file), "status": "interrupted" if isinstance(
                exc, KeyboardInterrupt) else "failed", "error": str(exc) or type(exc).__name__}
            try:
                directory.finish(failed, directory.commit(failed))
            except OutputError as write_error:  # never hides the error that ended the sweep
                echo(f"{write_error}; sweep.json still says the sweep is unfinished")
            raise
        files = directory.commit(result)
        directory.finish(result, files)
    finally:
        directory.release()
    out = directory.path
    echo(f"sweep done in {result['wall_time_s']:.1f} s: {out / 'sweep.md'}")
    return result


def _sweep(file: str | Path, loaded: Any, base: Any, points: list[Point], varies: list[Vary],
           baseline: dict[str, Any], out: Path, final: Path, options: SweepOptions,
           started: float, load_before: float | None) -> dict[str, Any]:
    """Run the trials into ``out`` (the staging folder) and write the tables beside them;
    what ``sweep.json`` will say (its paths are where the files are once moved into
    ``final``)."""
    echo = options.echo
    plugin_dir = str(Path.cwd()) if options.plugin_modules else None
    seed = int(base.seed)
    fixed = parse_overrides(["run.figures=false", "run.record=false"])
    tasks: list[TrialTask] = []
    invalid: dict[int, str] = {}
    for index, point in enumerate(points):
        point_overrides = (*options.overrides, *(Override(p, v, f"{p}={flow_text(v)}")
                                                 for p, v in point.values))
        try:  # a value validation refuses is this point's row, not the sweep's end
            validate_with_overrides(loaded, point_overrides,
                                    plugin_modules=options.plugin_modules,
                                    plugin_dir=plugin_dir)
        except (ExperimentError, UsageError) as exc:
            invalid[index] = str(exc)
            continue
        for trial in range(options.trials):
            trial_seed = seed + trial
            tasks.append(TrialTask(
                index, trial, trial_seed, loaded,
                (*point_overrides, *fixed, Override("seed", trial_seed, f"seed={trial_seed}")),
                str(out / "points" / _point_dir(index) / f"trial-{trial}"),
                options.timeout_s, options.plugin_modules, plugin_dir))
    workers = max(1, min(int(options.workers or os.cpu_count() or 1), max(1, len(tasks))))
    echo(f"sweep of {file}: {len(points)} points ({len(invalid)} refused) x "
         f"{options.trials} trials = {len(tasks)} runs on {workers} "
         f"{options.executor} worker{'s' if workers > 1 else ''}")
    done = 0

    def on_row(row: Mapping[str, Any], running: int) -> None:
        nonlocal done
        done += 1
        point = points[row["point"]]
        what = row["status"] if row["status"] != "ok" else _brief(row["metrics"])
        wall = row.get("wall_time_s")
        echo(f"[{done}/{len(tasks)}] {point.label} trial {row['trial']}: {what}"
             + (f" ({wall:.2f} s)" if isinstance(wall, float) else "")
             + (f"; {row['error']}" if row.get("error") else "")
             + f" ({min(running, workers)} running)")

    rows: list[dict[str, Any]] = []
    warm = None
    # A run that trains first (run.train_from) takes a minute or more: a first-call cost
    # is noise beside it, and warming up would train once more per worker.
    if (tasks and options.executor == "process"
            and not getattr(base.model.run, "train_from", None)):
        echo("each worker warms up first: one untimed run of the first point")
        warm = dataclasses.replace(tasks[0], out_dir=str(out / "warm-up"))
    if tasks:
        with make_executor(options.executor, workers, options.scheduler, warm) as executor:
            rows = _gather(executor, tasks, workers, options.timeout_s, on_row,
                           warmed=warm is not None)
        _mark_nan_against_baseline(rows)
    for row in rows:  # where each trial's directory is once the staging folder moves in
        if isinstance(row.get("run_dir"), str) and Path(row["run_dir"]).is_relative_to(out):
            row["run_dir"] = str(final / Path(row["run_dir"]).relative_to(out))
    summaries = []
    for index, point in enumerate(points):
        summary = _summarise_point(point, [r for r in rows if r["point"] == index])
        if index in invalid:
            summary["status"], summary["errors"] = "invalid", [invalid[index]]
        summary["dir"] = str(Path("points") / _point_dir(index))
        summaries.append(summary)
    keys = sorted({k for s in summaries for k in s["metrics"]})
    measure = accuracy_measure(keys)
    _mark_front(summaries, measure)
    result: dict[str, Any] = {
        "experiment_file": str(file),
        "mode": "grid" if options.grid else "one at a time",
        "trials": options.trials,
        "seeds": [seed + i for i in range(options.trials)],
        "executor": options.executor,
        "workers": workers,
        "timeout_s": options.timeout_s,
        "overrides": [o.text for o in options.overrides],
        "knobs": [{"path": v.path, "values": list(v.values), "baseline":
                   None if baseline[v.path] is _MISSING else baseline[v.path],
                   "trades": v.trades} for v in varies],
        "accuracy": None if measure is None else {"metric": measure[0],
                                                   "description": measure[1]},
        "front": [s["label"] for s in summaries if s.get("front")],
        "front_cpu": [s["label"] for s in summaries if s.get("front_cpu")],
        "points": summaries,
        "runs": rows,
        "warm_up": warm is not None,
        "wall_time_s": time.perf_counter() - started,
        "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count(),
                    "python": platform.python_version(),
                    "load_average_1min": {"start": load_before, "end": _load_average()}},
    }
    result = _json_ready(result)
    from hapticframe.sweep._sweep_report import render_markdown, save_pareto_figure

    atomic_write(out / "sweep.md", render_markdown(result))
    if not save_pareto_figure(out / "pareto.png", result):
        echo("pareto.png skipped: matplotlib is not installed")
    result["status"] = "ok"
    return result


def _brief(metrics: Mapping[str, Any]) -> str:
    parts = []
    for key in ("object_found", "centroid_error_m"):
        if key in metrics:
            value = metrics[key]
            parts.append(f"{key}={format_value(value)}")
    parts += [f"{k}={format_value(v)}" for k, v in metrics.items()
              if k.endswith("_balanced_accuracy")]
    return "ok " + ", ".join(parts) if parts else "ok"


#: The time a front weighs accuracy against: ``front`` (mean wall time per run) and
#: ``front_cpu`` (mean CPU time per run: on a busy machine wall time also counts the wait
#: for a core, CPU time does not).
_FRONTS = (("front", "wall_time_s"), ("front_cpu", "cpu_time_s"))


def _mark_front(summaries: list[dict[str, Any]],
                measure: tuple[str, str, Callable[[float], float]] | None) -> None:
    """Mark the points on each front (see :data:`_FRONTS`).

    A search point that found the object in a smaller share of its trials than the best
    points did is kept off the fronts (``off_front`` says why): a search that misses the
    object ends early and reports a centroid error for whatever blob it has, so it would
    otherwise sit on the front as the fastest setting.
    """
    eligible: list[int] = []
    for i, summary in enumerate(summaries):
        summary["accuracy_cost"] = None
        summary["off_front"] = None
        for key, _ in _FRONTS:
            summary[key] = False
        if measure is None or summary["status"] not in ("ok",):
            continue
        value = summary["metrics"].get(measure[0])
        if value is None:
            continue
        summary["accuracy_cost"] = measure[2](value)
        eligible.append(i)
    shares = {i: summaries[i]["metrics"].get("object_found") for i in eligible}
    known = [v for v in shares.values() if isinstance(v, (int, float))]
    if known:
        best = max(known)
        for i, share in shares.items():
            if isinstance(share, (int, float)) and share < best - 1e-9:
                summaries[i]["off_front"] = (f"found the object in {share:.0%} of its trials, "
                                             f"the best points in {best:.0%}")
        eligible = [i for i in eligible if summaries[i]["off_front"] is None]
    for key, cost_key in _FRONTS:
        candidates = [(i, (summaries[i]["cost"].get(cost_key), summaries[i]["accuracy_cost"]))
                      for i in eligible if summaries[i]["cost"].get(cost_key) is not None]
        for k in pareto_front([c[1] for c in candidates]):
            summaries[candidates[k][0]][key] = True


def _load_average() -> float | None:
    """The machine's 1-minute load average (None where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None




def _json_ready(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    return value
