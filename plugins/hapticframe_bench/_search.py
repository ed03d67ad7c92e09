"""``hapticframe bench search``: the simulated haptic-search study of Table 3.2.

Protocol (Jia 2022, section 3.5.2.1): for each of two shapes, a circle of 8 cm diameter
and a 9 x 5 cm ellipse, ``N`` trials bury the object at a random position and orientation
fully inside the 75 x 50 cm region and run a complete haptic search. Every placement is
searched three times, each through the core's public :func:`hapticframe.run_experiment`:
by the thesis's two-phase planner with the bundled (tuned) defaults, by the same planner
with the dissertation's own Table 3.1 parameters (role ``thesis-params``), and by the exhaustive
``coverage`` baseline.

Outputs in ``options.out_dir``:

* ``trials/<shape>-<i>-<planner>/`` (``<shape>-<i>-thesis-params/`` for the thesis's
  configuration): every run's own files (figures only for trial 0 of
  each shape: later trials run with ``run.figures: false``) and, once the run has finished,
  ``bench-trial.json`` (see below),
* ``search.json``: the summary (see :func:`run_suite`),
* ``search.md``: a table in the form of Table 3.2 beside the thesis's figures,
* ``search.png``: per-trial centroid error and Hausdorff distance.

Interruptions and resuming: each completed trial's record is kept in its run directory as
``bench-trial.json`` (written to a temporary name and renamed, so it is whole or absent),
stamped with a fingerprint of the trial's experiment, the library versions and the source
of hapticframe and its plugins (:func:`trial_fingerprint`). A trial directory counts as
finished only when that file exists with a matching fingerprint. Run the same command into
the same ``out_dir`` after an interruption and it reuses every finished trial (its progress
line says ``kept``) and runs the rest from scratch, clearing what an interrupted run left in
their directories first; the summary is the one an uninterrupted run writes (bar wall
times). A failed trial is not kept: the next run tries it again.

Worker processes die with the suite's process, even when it is killed with ``SIGKILL``:
each asks Linux to kill it when its parent dies (``PR_SET_PDEATHSIG``) and, on every
platform, watches its parent from a thread and exits once it has gone.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import math
import multiprocessing
import os
import platform
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

import hapticframe
from hapticframe import (
    BenchOptions,
    RunError,
    apply_overrides,
    atomic_write,
    run_experiment,
    validate_with_overrides,
)

from ._aggregate import aggregate_trials, trial_figures
from ._placements import (
    MULTI_SCENES,
    POLYGON_SHAPES,
    SCENE_SETS,
    SHAPES,
    Placement,
    draw_placements,
)
from ._report import THESIS_TABLE_3_2, render_markdown, save_trial_figure
from ._targets import Target, check_lines, check_targets
from ._template import REGION_HEIGHT_M, REGION_WIDTH_M, search_experiment, thesis_experiment

__all__ = [
    "BASELINE_PLANNER",
    "DEFAULT_TRIALS",
    "QUICK_TRIALS",
    "SEARCH_PLANNER",
    "THESIS_ROLE",
    "TRIAL_FILE",
    "run_search",
    "run_search_scenes",
    "run_suite",
    "search_targets",
    "trial_fingerprint",
    "trial_seed",
    "trials_for",
]

#: Trials per shape in the thesis, and in a quick run.
DEFAULT_TRIALS = 25
QUICK_TRIALS = 5
#: The planner under test and the baseline it is compared with.
SEARCH_PLANNER = "two-phase-coverage"
BASELINE_PLANNER = "coverage"
#: The role that runs the two-phase planner with the dissertation's Table 3.1 parameters
#: (:func:`~hapticframe_bench._template.thesis_experiment`) instead of the tuned defaults.
THESIS_ROLE = "thesis-params"

#: The whole command's wall time at the thesis's 25 trials per shape, on 2 free cores, for
#: two configurations (planner and baseline; a third adds half again).
WALL_TIME_TARGET_S = 60.0

ExperimentFactory = Callable[[Sequence[Mapping[str, Any]], str, int, str], dict[str, Any]]

#: A finished trial's record, in its run directory; the directory holds a finished trial
#: only when this file exists.
TRIAL_FILE = "bench-trial.json"


def trial_seed(seed: int, shape: str, index: int) -> int:
    """The experiment seed of one trial: fixed by the suite's seed, the shape and the index.

    Both planners of a trial share it. Derived with :class:`numpy.random.SeedSequence`, so
    it does not depend on the number of trials.
    """
    known = (*SHAPES, *POLYGON_SHAPES, *MULTI_SCENES)
    shape_number = known.index(shape) if shape in known else len(known)
    state = np.random.SeedSequence([int(seed), shape_number, int(index)]).generate_state(1)
    return int(state[0])


def trials_for(options: BenchOptions) -> int:
    """Trials per shape: ``options.trials``, else 5 for a quick run, else the thesis's 25.

    Raises
    ------
    ValueError
        When ``options.trials`` is not a positive int.
    """
    trials = options.trials if options.trials is not None else (
        QUICK_TRIALS if options.quick else DEFAULT_TRIALS)
    if not isinstance(trials, int) or isinstance(trials, bool) or trials < 1:
        raise ValueError(f"trials must be a positive int, got {trials!r}")
    return trials


def _git_commit() -> str | None:
    """The commit of a hapticframe source checkout (``-dirty`` with local changes), else None."""
    where = Path(hapticframe.__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=where, capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain"], cwd=where,
                                capture_output=True, text=True, timeout=10, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None  # an installed package, or no git: the versions must do
    return f"{head}-dirty" if status.strip() else head


@functools.lru_cache(maxsize=1)
def _environment_versions() -> tuple[tuple[str, Any], ...]:
    """Versions of the code and libraries, looked up once per process (about 45 ms, with
    two ``git`` calls: every trial of a suite runs in the same environment)."""
    versions: dict[str, Any] = {
        "hapticframe": hapticframe.__version__,
        "git_commit": _git_commit(),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
    for package in ("scipy", "pydantic", "matplotlib"):
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            versions[package] = None
    return tuple(versions.items())


def _versions(experiment: hapticframe.Experiment) -> dict[str, Any]:
    versions: dict[str, Any] = dict(_environment_versions())
    versions["plugins"] = {
        f"{entry.kind.value}/{entry.type}": f"{entry.registered.source.distribution} "
        f"{entry.registered.source.version}"
        for entry in experiment.components
    }
    return versions


def _force_limit_n(experiment: hapticframe.Experiment) -> float | None:
    """The sandbox robot's force limit as configured (None for another robot)."""
    for robot in experiment.resolved_config().get("robots", []):
        limit = robot.get("config", {}).get("force_limit_n")
        if limit is not None:
            return float(limit)
    return None


def _command(options: BenchOptions, trials: int) -> str:
    parts = ["hapticframe", "bench", "search", "--trials", str(trials), "--seed",
             str(options.seed), "--out", str(options.out_dir)]
    if options.quick:
        parts.append("--quick")
    for override in options.overrides:
        parts.extend(["--set", override])
    return " ".join(parts)


def _progress(record: Mapping[str, Any], done: int, total: int, *, kept: bool = False) -> str:
    role = record.get("role")
    who = ("Table 3.1 params" if role == THESIS_ROLE
           else record["planner"] if role in (None, "search", "baseline") else str(role))
    head = (f"[{done:>3}/{total}] {record['shape']:<7} trial {record['index']:<3} "
            f"{who:<19}")
    if kept:
        head += " kept from an earlier run:"
    if record["status"] != "ok":
        return f"{head} FAILED after {record['wall_time_s']:.1f} s: {record['error']}"
    f = record["figures"]

    def cm(key: str) -> str:
        value = f.get(key)
        return "   –   " if value is None else f"{value * 100:5.1f} cm"

    force = f.get("max_force_n")
    if f.get("objects_total") is not None:
        found = (f"found {f.get('objects_found')}/{f['objects_total']}, "
                 f"{f.get('false_blobs')} false")
    else:
        found = "found    " if f["object_found"] else "NOT FOUND"
    return (
        f"{head} {found}"
        f" centroid {cm('centroid_error_m')}"
        f"  Hausdorff {cm('hausdorff_m')}  EMs {f.get('ems_phase1')}+{f.get('ems_phase2')}"
        f"  max force {'–' if force is None else f'{force:.0f} N'}"
        f"  {record['wall_time_s']:.1f} s"
    )


# --- kept trials ---------------------------------------------------------------------------

#: Packages whose code decides a trial's result besides the registered plugins' own.
_FINGERPRINT_PACKAGES = ("hapticframe", __name__.split(".")[0])


@functools.lru_cache(maxsize=1)
def _code_digest() -> str:
    """sha256 over the source of hapticframe, this suite and every registered plugin package.

    Looked up once per process; an edit to any of them retires kept trials.
    """
    packages = set(_FINGERPRINT_PACKAGES)
    packages.update(entry.source.module.split(".")[0] for entry in hapticframe.get_registry())
    digest = hashlib.sha256()
    for package in sorted(packages):
        spec = importlib.util.find_spec(package)
        roots = list(spec.submodule_search_locations or ()) if spec is not None else []
        if spec is not None and not roots and spec.origin:
            roots = [spec.origin]  # a single-module plugin
        digest.update(f"package {package}\n".encode())
        for root in map(Path, roots):
            sources = sorted(root.rglob("*.py")) if root.is_dir() else [root]
            for source in sources:
                digest.update(source.relative_to(root.parent).as_posix().encode())
                digest.update(source.read_bytes())
    return digest.hexdigest()


def trial_fingerprint(experiment: Mapping[str, Any], role: str) -> str:
    """A digest of what one trial's record depends on.

    The trial's experiment mapping (scene, planner, seed, figures, name), its role, the
    library versions and the source of hapticframe, this suite and the registered plugins.
    """
    environment = dict(_environment_versions())
    environment.pop("git_commit", None)  # the source digest is finer (it sees local edits)
    digest = hashlib.sha256(json.dumps(
        {"experiment": experiment, "role": role, "environment": environment},
        sort_keys=True, default=repr).encode())
    digest.update(_code_digest().encode())
    return digest.hexdigest()


TrialResult = tuple[dict[str, Any], dict[str, Any], float | None, float]


def _kept_trial(run_dir: Path, fingerprint: str, placement: Placement,
                role: str) -> TrialResult | None:
    """A trial finished by an earlier run with the same fingerprint, else None."""
    try:
        kept = json.loads((run_dir / TRIAL_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # absent, unreadable or not JSON: not finished
    if not isinstance(kept, dict) or kept.get("fingerprint") != fingerprint:
        return None
    record, versions = kept.get("record"), kept.get("versions")
    if not (isinstance(record, dict) and isinstance(versions, dict)
            and isinstance(versions.get("plugins"), dict) and record.get("status") == "ok"
            and isinstance(record.get("figures"), dict)
            and (record.get("shape"), record.get("index"), record.get("role"))
            == (placement.shape, placement.index, role)):
        return None
    limit, level = kept.get("force_limit_n"), kept.get("outline_level")
    if not isinstance(level, (int, float)) or not isinstance(limit, (int, float, type(None))):
        return None
    return record, versions, None if limit is None else float(limit), float(level)


def _keep_trial(run_dir: Path, fingerprint: str, result: TrialResult) -> None:
    """Mark a run directory finished: its record, written whole or not at all."""
    record, versions, limit, level = result
    text = json.dumps(_json_ready({"fingerprint": fingerprint, "record": record,
                                   "versions": versions, "force_limit_n": limit,
                                   "outline_level": level}), allow_nan=False)
    run_dir.mkdir(parents=True, exist_ok=True)
    partial = run_dir / (TRIAL_FILE + ".part")
    partial.write_text(text + "\n", encoding="utf-8")
    os.replace(partial, run_dir / TRIAL_FILE)  # atomic: a kill leaves the old state or this


def _clear(run_dir: Path) -> None:
    """Remove what an interrupted or stale trial left, so the trial runs from scratch."""
    if run_dir.is_symlink() or run_dir.is_file():
        run_dir.unlink()
    elif run_dir.exists():
        shutil.rmtree(run_dir)


# --- running trials ------------------------------------------------------------------------


def _run_trial(
    placement: Placement,
    role: str,
    planner: str,
    seed: int,
    trials_dir: Path,
    data: dict[str, Any],
    fingerprint: str,
    overrides: tuple[str, ...] = (),
) -> TrialResult:
    name = _run_name(placement.shape, placement.index, role, planner)
    # The overrides (`--set`) are applied here too, so that run.json records them.
    experiment = validate_with_overrides(data, overrides, source=f"<bench search {name}>")
    run_dir = trials_dir / name
    record: dict[str, Any] = {
        "shape": placement.shape,
        "index": placement.index,
        "role": role,
        "planner": planner,
        "seed": seed,
        "placement": placement.to_dict(),
        "run_dir": str(Path("trials") / name),
        "status": "ok",
        "error": None,
        "figures": None,
    }
    _clear(run_dir)  # nothing of an interrupted attempt mixes with this one
    started = time.perf_counter()
    try:
        metrics = run_experiment(experiment, run_dir, overwrite=True, echo=lambda _line: None)
        record["figures"] = trial_figures(metrics)
    except RunError as exc:
        record["status"] = "failed"
        record["error"] = str(exc)
    finally:
        record["wall_time_s"] = time.perf_counter() - started
    result = (record, _versions(experiment), _force_limit_n(experiment),
              experiment.resolved_config()["run"]["outline_level"])
    if record["status"] == "ok":
        _keep_trial(run_dir, fingerprint, result)
    return result


def _run_name(shape: str, index: int, role: str, planner: str) -> str:
    """A trial run's directory name: the planner's (roles search, baseline), else the role."""
    return f"{shape}-{index}-{planner if role in ('search', 'baseline') else role}"


def _run_job(job: tuple[Any, ...]) -> TrialResult:
    return _run_trial(*job)


#: Seconds between a worker's looks at its parent (the fallback where prctl is missing).
_PARENT_POLL_S = 0.5
#: Linux's prctl option that sends a signal to this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> bool:
    """Ask Linux to SIGKILL this process when its parent dies; False where unavailable."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        # prctl is variadic: pass unsigned longs, as the kernel reads them.
        return int(libc.prctl(_PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGKILL),
                              ctypes.c_ulong(0), ctypes.c_ulong(0), ctypes.c_ulong(0))) == 0
    except (OSError, AttributeError):
        return False


def _watch_parent(
    parent: int,
    interval_s: float = _PARENT_POLL_S,
    *,
    getppid: Callable[[], int] = os.getppid,
    sleep: Callable[[float], None] = time.sleep,
    exit_now: Callable[[int], Any] = os._exit,
) -> None:
    """Return only by ending the process, once its parent is no longer ``parent``.

    An orphan is adopted by init or a subreaper, so its parent id changes.
    """
    while getppid() == parent:
        sleep(interval_s)
    exit_now(1)


def _init_worker(expected_parent: int | None) -> None:
    """A pool worker's initializer: the worker dies with the process that started it."""
    _die_with_parent()
    parent = os.getppid()
    if expected_parent is not None and parent != expected_parent:
        os._exit(1)  # the parent died before the request above could take effect
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True,
                     name="hapticframe-bench-parent-watch").start()


def _pool_context() -> Any:
    """fork on Linux, as the perception bench (workers start without importing again);
    the platform's default elsewhere."""
    if sys.platform.startswith("linux"):
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context()


def _map_jobs(jobs: list[tuple[Any, ...]], workers: int) -> Any:
    """Run the trials, in worker processes when there is more than one worker.

    Trials are independent and seeded, so results do not depend on the number of workers.
    The workers die with this process (:func:`_init_worker`).
    """
    if workers <= 1:
        yield from map(_run_job, jobs)
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed

    context = _pool_context()
    # A forkserver's children are the server's, not ours: they watch whichever parent
    # they have (the server dies with this process).
    expected = None if context.get_start_method() == "forkserver" else os.getpid()
    with ProcessPoolExecutor(max_workers=workers, mp_context=context,
                             initializer=_init_worker, initargs=(expected,)) as pool:
        futures = [pool.submit(_run_job, job) for job in jobs]
        for future in as_completed(futures):
            yield future.result()


def _summarise(
    records: Sequence[Mapping[str, Any]], shapes: Sequence[str], force_limit_n: float | None
) -> dict[str, Any]:
    def group(shape: str, role: str) -> dict[str, Any]:
        chosen = [r for r in records if r["shape"] == shape and r["role"] == role]
        return aggregate_trials(chosen, force_limit_n)

    out: dict[str, Any] = {shape: group(shape, "search") for shape in shapes}
    out["baseline"] = {shape: group(shape, "baseline") for shape in shapes}
    if any(r["role"] == THESIS_ROLE for r in records):
        out["thesis_params"] = {shape: group(shape, THESIS_ROLE) for shape in shapes}
    for role in sorted({str(r["role"]) for r in records} - {"search", "baseline", THESIS_ROLE}):
        out[role] = {shape: group(shape, role) for shape in shapes}
    return out


def _json_ready(value: Any) -> Any:
    """Plain JSON data with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, (np.generic,)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def search_targets(summary: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Each target of the suite with its measurement and verdict (``search.json``'s ``targets``).

    Per shape, the two-phase planner against Table 3.2: total movements (phase 1 + 2, mean)
    at most the thesis's, centroid RMSE and mean Hausdorff distance at most the thesis's
    means. At the thesis's 25 trials per shape, also the whole command's wall time
    (at most 30 s per configuration run, on 2 free cores; not measured when the run resumed
    kept runs).
    """
    values: dict[str, Any] = {}
    targets: list[Target] = []

    def mean(group: Mapping[str, Any], key: str) -> float | None:
        stats = group.get(key)
        return stats.get("mean") if isinstance(stats, Mapping) else None

    for shape in summary.get("shapes", ()):
        thesis = THESIS_TABLE_3_2.get(shape)
        group = summary.get(shape)
        if thesis is None or not isinstance(group, Mapping):
            continue
        phases = (mean(group, "ems_phase1"), mean(group, "ems_phase2"))
        p1, p2 = phases
        values[f"{shape}_total_ems"] = None if p1 is None or p2 is None else p1 + p2
        rmse = group.get("centroid_rmse_m")
        values[f"{shape}_centroid_rmse_cm"] = None if rmse is None else 100 * rmse
        hausdorff = mean(group, "hausdorff_m")
        values[f"{shape}_hausdorff_cm"] = None if hausdorff is None else 100 * hausdorff
        targets += [
            Target(f"{shape}_total_ems", f"{shape}: movements, phase 1 + 2",
                   thesis["ems_phase1"][0] + thesis["ems_phase2"][0], digits=2),
            Target(f"{shape}_centroid_rmse_cm", f"{shape}: centroid RMSE",
                   100 * thesis["centroid_rmse_m"][0], "cm", digits=2),
            Target(f"{shape}_hausdorff_cm", f"{shape}: Hausdorff distance",
                   100 * thesis["hausdorff_m"][0], "cm", digits=2),
        ]
    if summary.get("trials") == DEFAULT_TRIALS:
        # A resumed run's wall time leaves out the kept runs: not a measurement of the whole.
        values["wall_time_s"] = (None if summary.get("kept_runs")
                                 else summary.get("wall_time_s"))
        # The target was set for two configurations (planner and baseline); each further
        # one (the thesis's parameters) adds its share.
        configurations = len(summary.get("planners") or {}) or 2
        targets.append(Target("wall_time_s", f"whole command, wall time ({configurations} "
                              "configurations)", WALL_TIME_TARGET_S * configurations / 2, "s"))
    return {c.target.name: c.as_dict() for c in check_targets(targets, values)}


def run_suite(
    options: BenchOptions,
    *,
    experiment_factory: ExperimentFactory = search_experiment,
    shapes: Sequence[str] = SHAPES,
    planners: Mapping[str, str] | None = None,
    report_name: str = "search",
    role_experiments: Mapping[str, Callable[[dict[str, Any]], dict[str, Any]]] | None = None,
) -> dict[str, Any]:
    """Run the search benchmark and write its report (see the module docstring).

    Parameters
    ----------
    options : hapticframe.BenchOptions
        ``trials`` per shape (default 25, or 5 with ``quick``), ``seed`` (placements come
        from ``numpy.random.default_rng(seed)``), ``out_dir`` and ``echo`` (one line per
        run).
    experiment_factory : callable
        Builds one trial's experiment mapping as
        ``factory(scene_objects, planner_type, seed, name)``; the default is the thesis's
        set-up, :func:`~hapticframe_bench._template.search_experiment`.
    shapes : sequence of str
        Shapes to bury (default: circle and ellipse), or multi-object scenes
        (:data:`~hapticframe_bench._placements.MULTI_SCENES`, searched with the two-phase
        planner's ``max_objects: null``).
    planners : mapping of str to str, optional
        Role (``"search"``, ``"thesis-params"``, ``"baseline"``) to planner type; default: the
        two-phase planner as ``"search"`` (the bundled defaults) and as ``"thesis-params"`` (Table
        3.1's parameters, :func:`~hapticframe_bench._template.thesis_experiment`), and the
        coverage planner as ``"baseline"``. A role left out is not run (its aggregates are
        then empty; the summary has no ``"thesis_params"`` without it).
    report_name : str
        Stem of the report files (``search`` writes search.json, search.md, search.png).
    role_experiments : mapping of str to callable, optional
        Role to a function that changes the role's trial experiment (after the factory;
        e.g. another sensor chain). A role other than ``"search"``, ``"baseline"`` and
        ``"thesis-params"`` runs in ``<shape>-<i>-<role>/`` and is summarised under its name.

    Returns
    -------
    dict
        The summary written to ``search.json``: one aggregate (see
        :func:`~hapticframe_bench._aggregate.aggregate_trials`) per shape for the two-phase
        planner at the top level, the same under ``"baseline"`` for the coverage planner
        and under ``"thesis_params"`` for the thesis's configuration,
        ``wall_time_s`` (of this invocation), ``kept_runs`` (runs reused from an earlier,
        interrupted run into the same ``out_dir``; see the module docstring), ``trials``,
        ``seed``, ``versions``, ``machine``, ``command``,
        ``planners``, ``thesis`` (Table 3.2), ``targets`` (:func:`search_targets`) and
        ``runs`` (every run's record).
    """
    trials = trials_for(options)
    shapes = tuple(shapes)
    out_dir = Path(options.out_dir)
    trials_dir = out_dir / "trials"
    trials_dir.mkdir(parents=True, exist_ok=True)
    placements = draw_placements(
        np.random.default_rng(options.seed), trials, (0.0, REGION_WIDTH_M, 0.0, REGION_HEIGHT_M),
        shapes,
    )
    if planners is None:
        planners = {"search": SEARCH_PLANNER, THESIS_ROLE: SEARCH_PLANNER,
                    "baseline": BASELINE_PLANNER}
    planners = dict(planners)
    total = trials * len(shapes) * len(planners)
    records: list[dict[str, Any]] = []
    versions: dict[str, Any] = {}
    force_limit_n: float | None = None
    outline_level: float | None = None
    started = time.perf_counter()
    options.echo(f"search benchmark: {trials} trials x {len(shapes)} shapes x "
                 f"{len(planners)} planners = {total} runs into {trials_dir}")
    jobs = []
    for index in range(trials):
        for shape in shapes:
            for role, planner in planners.items():
                placement = placements[shape][index]
                seed = trial_seed(options.seed, shape, index)
                objects = placement.scene_objects()
                data = experiment_factory(objects, planner, seed,
                                          _run_name(shape, index, role, planner))
                if role == THESIS_ROLE:
                    data = thesis_experiment(data)
                if role_experiments and role in role_experiments:
                    data = role_experiments[role](data)
                if len(objects) > 1 and planner == SEARCH_PLANNER:
                    # Every object: phase 1 resumes after each outline (issue 19).
                    for entry in data.get("planners", []):
                        entry.setdefault("config", {})["max_objects"] = None
                # Figures only for the first trial of each shape: drawing costs more than a
                # fast search.
                data.setdefault("run", {})["figures"] = index == 0
                # A `--set` changes the trial's experiment, so its fingerprint too.
                changed, _applied = apply_overrides(data, options.overrides)
                jobs.append((placement, role, planner, seed, trials_dir, data,
                             trial_fingerprint(changed, role), tuple(options.overrides)))
    if options.overrides:
        # A bad `--set` is refused before any run, as `hapticframe run` refuses it.
        for role in planners:
            first = next(j for j in jobs if j[1] == role)
            validate_with_overrides(first[5], first[7], source=f"<bench search {role}>")
    kept = [_kept_trial(trials_dir / _run_name(j[0].shape, j[0].index, j[1], j[2]), j[6], j[0],
                        j[1])
            for j in jobs]
    todo = [job for job, result in zip(jobs, kept, strict=True) if result is None]
    if len(todo) < len(jobs):
        options.echo(f"resuming: {len(jobs) - len(todo)} of {total} runs kept from "
                     f"{trials_dir}")

    def collect(result: TrialResult, *, was_kept: bool) -> None:
        nonlocal versions, force_limit_n, outline_level
        record, run_versions, limit, level = result
        if not versions:
            versions, force_limit_n, outline_level = run_versions, limit, level
        else:  # the baseline's planner joins the plugin list
            versions["plugins"].update(run_versions["plugins"])
        records.append(record)
        options.echo(_progress(record, len(records), total, kept=was_kept))

    for result in kept:
        if result is not None:
            collect(result, was_kept=True)
    workers = min(options.workers or os.cpu_count() or 1, len(todo))
    for result in _map_jobs(todo, workers):
        collect(result, was_kept=False)
    order = {(j[0].shape, j[0].index, j[1]): k for k, j in enumerate(jobs)}
    records.sort(key=lambda r: order[(r["shape"], r["index"], r["role"])])
    wall_time_s = time.perf_counter() - started
    summary: dict[str, Any] = _summarise(records, shapes, force_limit_n)
    summary.update({
        "wall_time_s": wall_time_s,
        "kept_runs": len(jobs) - len(todo),
        "trials": trials,
        "seed": options.seed,
        "quick": options.quick,
        "shapes": list(shapes),
        "planners": planners,
        "outline_level": outline_level,
        "force_limit_n": force_limit_n,
        "versions": versions,
        "machine": {
            "platform": platform.platform(),
            "processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(),
            "python": platform.python_version(),
        },
        "command": _command(options, trials),
        "overrides": list(options.overrides),
        "thesis": {shape: {k: list(v) for k, v in row.items()}
                   for shape, row in THESIS_TABLE_3_2.items()},
        "runs": records,
    })
    summary["targets"] = search_targets(summary)
    summary = _json_ready(summary)
    text = json.dumps(summary, indent=2, sort_keys=False, allow_nan=False)
    atomic_write(out_dir / f"{report_name}.json", text + "\n")
    atomic_write(out_dir / f"{report_name}.md", render_markdown(summary))
    if not save_trial_figure(out_dir / f"{report_name}.png", summary):
        options.echo(f"{report_name}.png skipped: matplotlib is not installed")
    for check in check_lines(summary["targets"]):
        options.echo(check)
    options.echo(f"search benchmark done in {wall_time_s:.1f} s: {out_dir / f'{report_name}.md'}")
    return summary


def run_search(options: BenchOptions) -> dict[str, Any]:
    """``hapticframe bench search``: Table 3.2's protocol with the bundled plugins.

    See :func:`run_suite` for the options used and the summary returned.
    """
    return run_suite(options)


#: The scene sets ``bench search-scenes`` runs, in order.
SCENE_SET_ORDER = ("polygons", "multi")


def run_search_scenes(options: BenchOptions) -> dict[str, Any]:
    """``hapticframe bench search-scenes``: the scenes beyond Table 3.2 (issue 19 §3-§4).

    Polygon rows (an L-shape and a 5-point star of the 8 cm circle's area) and scenes of
    two and three objects at least 10 cm apart, each searched by the tuned two-phase
    planner (``max_objects: null`` for several objects) and the coverage baseline, with
    the protocol and options of :func:`run_suite`; reports ``search-scenes.json``/``.md``/
    ``.png``. A suite of its own so that ``bench search`` keeps Table 3.2's cost.
    """
    shapes = tuple(s for name in SCENE_SET_ORDER for s in SCENE_SETS[name])
    return run_suite(options, shapes=shapes,
                     planners={"search": SEARCH_PLANNER, "baseline": BASELINE_PLANNER},
                     report_name="search-scenes")
