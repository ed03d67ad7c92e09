"""``hapticframe bench fuzz``: mutants of the examples, each refused cleanly or run cleanly.

Issue 16: what ``validate`` accepts, ``run`` must survive. Mutants are drawn, from a seeded
generator, out of the bundled examples in these categories:

* ``number``: a numeric field set to an extreme (0, -1, ±1e308, NaN, ±inf, 1e-308, 1e12) or a
  boolean;
* ``type``: a field of the wrong type (a string, a list, a mapping, null);
* ``structure``: a key removed, an unknown key added, a component duplicated, inputs emptied
  or naming nothing, a component removed;
* ``text``: a name or type 100,000 characters long, or holding a NUL.

Each mutant is written as a YAML file and validated in this process; one that is refused
must be refused with exit 2 and every issue located (a line, and a dotted path below the top
level). One that is accepted is run in a child
process (``hapticframe run``, movements capped, a time limit and an address-space limit):
it must end with exit 0 and real metrics, or with a clear error (exit 1 or 2, no "internal
error"); a run that exits 2 was refused only when building, which counts as a failure (the
refusal belongs to ``validate``), and so does a time-out.

Issue 26 adds five families (:mod:`hapticframe_bench._fuzz_families`): damaged recordings
through ``recover``, ``report``, ``replay`` and the ``recording`` sensor; two writers into
one output directory; fault schedules per device; damaged ROS bags through ``import-bag``;
and a hostile client of the live server. Issue 36 adds three
(:mod:`hapticframe_bench._fuzz_doors`): hostile tables and layouts through ``import``,
hostile HDF5 files through the BOLT and Keras readers, and hostile ``.npz`` artifacts (the
response library, the raking estimator's weights); there a hang and a hostile file
accepted are findings too. Each case is refused (exit 2, located), ends
cleanly, or is a finding: an internal error, an exit 0 with a null or NaN result, or a lost
or mixed output (:mod:`hapticframe_bench._fuzz_common`). The report counts the three per
family.
"""

from __future__ import annotations

import copy
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hapticframe import (
    BenchOptions,
    ExperimentError,
    HapticframeError,
    atomic_write,
    validate_file,
)
from hapticframe_bench._fuzz_families import FAMILIES, run_families, tally

__all__ = [
    "CATEGORIES",
    "Mutant",
    "Outcome",
    "check_mutant",
    "generate_mutants",
    "run_fuzz",
]

CATEGORIES = ("number", "type", "structure", "text")
#: Examples whose mutants are also run (the others need recordings or trained models).
RUNNABLE = ("search-ellipse.yaml", "search-circle-baseline.yaml", "search-two-arms.yaml",
            "search-ellipse-ft300.yaml", "search-ellipse-dynamixel.yaml",
            "free-motion-ft300.yaml")
#: Numeric extremes a field is set to.
EXTREMES: tuple[Any, ...] = (0, -1, 1e308, -1e308, math.nan, math.inf, -math.inf, 1e-308,
                             10**12, True)
WRONG_TYPES: tuple[Any, ...] = ("x", [], {}, None)
#: A child run's limits: wall time, address space, movements.
RUN_TIMEOUT_S = 180.0
RUN_MEMORY_BYTES = 6 * 1024**3
MAX_MOVEMENTS = 3
DEFAULT_MUTANTS = 320
QUICK_MUTANTS = 60
#: Cases of each family of issue 26 (recordings, writers, faults, bags, live).
DEFAULT_CASES = 100
QUICK_CASES = 20


@dataclass(frozen=True)
class Mutant:
    """One mutated experiment: its source example, category, what changed, and the data."""

    example: str
    category: str
    change: str
    data: Any
    runnable: bool


@dataclass
class Outcome:
    """What became of a mutant: ``refused`` (at validate), ``ran`` (exit 0), ``failed_clean``
    (a clear run error), or a failure (``ok`` False) with the reason."""

    mutant: Mutant
    status: str
    ok: bool
    detail: str = ""
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


def _examples(root: Path) -> list[tuple[str, Any]]:
    out = []
    for path in sorted(root.glob("*.yaml")):
        out.append((path.name, yaml.safe_load(path.read_text(encoding="utf-8"))))
    return out


def _leaves(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _leaves(value, (*path, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _leaves(value, (*path, i))
    else:
        yield path, data


def _containers(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    if isinstance(data, dict):
        yield path, data
        for key, value in data.items():
            yield from _containers(value, (*path, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from _containers(value, (*path, i))


def _set(data: Any, path: tuple[Any, ...], value: Any) -> None:
    for key in path[:-1]:
        data = data[key]
    data[path[-1]] = value


def _get(data: Any, path: tuple[Any, ...]) -> Any:
    for key in path:
        data = data[key]
    return data


def _dotted(path: tuple[Any, ...]) -> str:
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in path).lstrip(".")


def _mutate(base: Any, category: str, rng: np.random.Generator) -> tuple[str, Any] | None:
    data = copy.deepcopy(base)
    if category == "number":
        numbers = [(p, v) for p, v in _leaves(data)
                   if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if not numbers:
            return None
        path, _ = numbers[int(rng.integers(len(numbers)))]
        value = EXTREMES[int(rng.integers(len(EXTREMES)))]
        _set(data, path, value)
        return f"{_dotted(path)} = {value!r}", data
    if category == "type":
        leaves = [(p, v) for p, v in _leaves(data) if p]
        path, _ = leaves[int(rng.integers(len(leaves)))]
        value = WRONG_TYPES[int(rng.integers(len(WRONG_TYPES)))]
        _set(data, path, value)
        return f"{_dotted(path)} = {value!r}", data
    if category == "text":
        targets = [("name",)] + [
            (section, i, key) for section in ("robots", "sensors", "classifiers", "maps")
            for i in range(len(data.get(section) or [])) for key in ("type", "id")
        ]
        path = targets[int(rng.integers(len(targets)))]
        value = "z" * 100_000 if rng.random() < 0.5 else "bad\x00name"
        _set(data, path, value)
        return f"{_dotted(path)} = <{len(value)} characters>", data
    # structure
    sections = [s for s in ("robots", "sensors", "feature_extractors", "classifiers",
                            "sensor_models", "maps", "planners") if data.get(s)]
    kind = int(rng.integers(6))
    if kind == 0:  # remove a key
        mappings = [(p, m) for p, m in _containers(data) if isinstance(m, dict) and m]
        path, mapping = mappings[int(rng.integers(len(mappings)))]
        key = list(mapping)[int(rng.integers(len(mapping)))]
        del mapping[key]
        return f"removed {_dotted((*path, key))}", data
    if kind == 1:  # an unknown key
        mappings = [(p, m) for p, m in _containers(data) if isinstance(m, dict)]
        path, mapping = mappings[int(rng.integers(len(mappings)))]
        mapping["zz_unknown"] = 1
        return f"added {_dotted((*path, 'zz_unknown'))}", data
    if not sections:
        return None
    section = sections[int(rng.integers(len(sections)))]
    items = data[section]
    i = int(rng.integers(len(items)))
    if kind == 2:
        items.append(copy.deepcopy(items[i]))
        return f"duplicated {section}[{i}]", data
    if kind == 3:
        items[i]["inputs"] = []
        return f"{section}[{i}].inputs = []", data
    if kind == 4:
        items[i]["inputs"] = ["nosuchcomponent"]
        return f"{section}[{i}].inputs = ['nosuchcomponent']", data
    del items[i]
    return f"removed {section}[{i}]", data


def generate_mutants(examples_dir: Path, count: int, seed: int = 0) -> list[Mutant]:
    """``count`` mutants of the examples in ``examples_dir``, categories in turn (seeded)."""
    rng = np.random.default_rng(seed)
    bases = _examples(examples_dir)
    mutants: list[Mutant] = []
    attempts = 0
    while len(mutants) < count and attempts < 20 * count:
        attempts += 1
        category = CATEGORIES[len(mutants) % len(CATEGORIES)]
        name, base = bases[int(rng.integers(len(bases)))]
        made = _mutate(base, category, rng)
        if made is None:
            continue
        change, data = made
        mutants.append(Mutant(name, category, change, data, name in RUNNABLE))
    return mutants


def _limit_memory() -> None:  # runs in the child before exec
    resource.setrlimit(resource.RLIMIT_AS, (RUN_MEMORY_BYTES, RUN_MEMORY_BYTES))


def check_mutant(mutant: Mutant, workdir: Path, *, run: bool = True,
                 max_movements: int = MAX_MOVEMENTS) -> Outcome:
    """Validate ``mutant`` here; run it in a child process when accepted (and ``run``), for
    at most ``max_movements`` movements."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    experiment = workdir / "experiment.yaml"
    # Validated as the file a user would write, so that every issue can name its line.
    experiment.write_text(yaml.safe_dump(mutant.data, allow_unicode=True), encoding="utf-8")
    try:
        validate_file(experiment)
    except ExperimentError as exc:
        unlocated = [i for i in exc.issues if i.line is None]
        long = [i for i in exc.issues if len(i.message) > 2000]
        ok = not unlocated and not long and exc.exit_code == 2
        detail = "" if ok else (f"{len(unlocated)} unlocated issue(s)" if unlocated
                                else "a message over 2000 characters")
        return Outcome(mutant, "refused", ok, detail, time.perf_counter() - started)
    except HapticframeError as exc:
        ok = exc.exit_code == 2
        return Outcome(mutant, "refused", ok, "" if ok else f"exit {exc.exit_code}: {exc}"[:300],
                       time.perf_counter() - started)
    except Exception as exc:  # an internal error at validate
        return Outcome(mutant, "internal_error", False,
                       f"validate raised {type(exc).__name__}: {exc}"[:300],
                       time.perf_counter() - started)
    if not (run and mutant.runnable):
        return Outcome(mutant, "accepted", True, "", time.perf_counter() - started)
    return _run_child(mutant, workdir, started, max_movements)


def _run_child(mutant: Mutant, workdir: Path, started: float, max_movements: int) -> Outcome:
    data = copy.deepcopy(mutant.data)
    data.setdefault("run", {})
    if isinstance(data["run"], dict):
        data["run"].update({"max_movements": max_movements, "figures": False})
    experiment = workdir / "run-experiment.yaml"
    experiment.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    out = workdir / "run"
    command = [sys.executable, "-m", "hapticframe", "run", str(experiment), "--out", str(out),
               "--quiet"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=RUN_TIMEOUT_S,
                              preexec_fn=_limit_memory if os.name == "posix" else None,
                              check=False)
    except subprocess.TimeoutExpired:
        return Outcome(mutant, "timeout", False, f"no end within {RUN_TIMEOUT_S:g} s",
                       time.perf_counter() - started)
    seconds = time.perf_counter() - started
    stderr = done.stderr.strip()
    last = stderr.splitlines()[-1] if stderr else ""
    if "internal error" in stderr or "Traceback" in stderr:
        return Outcome(mutant, "internal_error", False, last[:300], seconds)
    if done.returncode == 0:
        metrics_path = out / "metrics.json"
        if not metrics_path.exists():
            return Outcome(mutant, "no_metrics", False, "exit 0 without metrics.json", seconds)
        metrics = json.loads(metrics_path.read_text(encoding="utf-8"))
        if not isinstance(metrics.get("movements"), int):
            return Outcome(mutant, "null_metrics", False, "exit 0 without a movement count",
                           seconds)
        scene = data.get("scene") if isinstance(data, dict) else None
        has_objects = isinstance(scene, dict) and bool(scene.get("objects"))
        if has_objects and not isinstance(metrics.get("object_found"), bool):
            return Outcome(mutant, "null_metrics", False,
                           "exit 0 with buried objects, object_found not a bool", seconds)
        return Outcome(mutant, "ran", True, "", seconds)
    if done.returncode == 2:
        return Outcome(mutant, "refused_at_run", False, last[:300], seconds)
    if done.returncode == 1 and last.startswith("error:"):
        return Outcome(mutant, "failed_clean", True, last[:300], seconds)
    return Outcome(mutant, f"exit_{done.returncode}", False, last[:300], seconds)


def run_fuzz(options: BenchOptions, *, examples_dir: str | Path | None = None,
             check: Callable[..., Outcome] = check_mutant,
             families: tuple[str, ...] = FAMILIES) -> dict[str, Any]:
    """``hapticframe bench fuzz``: the examples' mutants (see the module docstring) and the
    families of issues 26 and 36 (``recordings``, ``writers``, ``faults``, ``bags``,
    ``live``, ``tables``, ``hdf5``, ``artifacts``: see
    :mod:`hapticframe_bench._fuzz_families`). ``--trials`` cases per family (default 320
    mutants and 100 cases of each other family; 60 and 20 with ``--quick``), ``--seed``;
    writes ``fuzz.json`` and ``fuzz.md`` into ``--out`` and returns the summary."""
    root = Path(examples_dir) if examples_dir is not None else _bundled_examples()
    count = options.trials or (QUICK_MUTANTS if options.quick else DEFAULT_MUTANTS)
    family_count = options.trials or (QUICK_CASES if options.quick else DEFAULT_CASES)
    mutants = generate_mutants(root, count, options.seed)
    out_dir = Path(options.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    outcomes: list[Outcome] = []
    load_before = os.getloadavg()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hapticframe-fuzz-") as tmp:
        for k, mutant in enumerate(mutants):
            outcome = check(mutant, Path(tmp) / f"m{k:04d}")
            outcomes.append(outcome)
            mark = "ok  " if outcome.ok else "FAIL"
            options.echo(f"[examples {k + 1:>4}/{len(mutants)}] {mark} {outcome.status:<15} "
                         f"{mutant.category:<9} {mutant.example}: {mutant.change[:70]}"
                         + (f" -> {outcome.detail[:120]}" if outcome.detail else ""))
        examples_s = time.perf_counter() - started
        by_family, notes = run_families(Path(tmp) / "families", root, family_count,
                                        options.seed, options.echo, families)
    failure_records = [{"family": "examples", "example": o.mutant.example,
                        "category": o.mutant.category, "change": o.mutant.change,
                        "status": o.status, "detail": o.detail}
                       for o in outcomes if not o.ok]
    for family, found in by_family.items():
        failure_records += [{"family": family, "kind": o.case.kind, "change": o.case.change,
                             "status": o.status, "detail": o.detail} for o in found if not o.ok]
    report = {"examples": tally(outcomes, examples_s)}
    for family, found in by_family.items():
        report[family] = tally(found, notes.get("seconds", {}).get(family, 0.0))
    summary: dict[str, Any] = {
        "cases": sum(r["cases"] for r in report.values()),
        "mutants": len(outcomes),
        "seed": options.seed,
        "families": report,
        "internal_errors": sum(r["internal_errors"] for r in report.values()),
        "exit0_null": sum(r["exit0_null"] for r in report.values()),
        "lost_or_mixed": sum(r["lost_or_mixed"] for r in report.values()),
        "hangs": sum(r["hangs"] for r in report.values()),
        "silently_accepted": sum(r["silently_accepted"] for r in report.values()),
        "other_findings": sum(r["other_findings"] for r in report.values()),
        "live_token_feature": notes.get("live_token_feature"),
        "fault_runs_cap": notes.get("fault_runs_cap"),
        "skipped": notes.get("skipped", {}),
        "failures": failure_records,
        "wall_time_s": time.perf_counter() - started,
        "machine": {"cpu_count": os.cpu_count(), "load_average_1min":
                    {"start": load_before[0], "end": os.getloadavg()[0]}},
    }
    atomic_write(out_dir / "fuzz.json", json.dumps(summary, indent=2) + "\n")
    atomic_write(out_dir / "fuzz.md", _markdown(summary))
    options.echo(f"fuzz: {summary['cases']} cases, {len(failure_records)} findings "
                 f"({out_dir / 'fuzz.md'})")
    return summary


def _markdown(summary: dict[str, Any]) -> str:
    machine = summary["machine"]
    load = machine["load_average_1min"]
    lines = ["# Fuzzing", "",
             f"{summary['cases']} cases, seed {summary['seed']}, "
             f"{summary['wall_time_s']:.0f} s on {machine['cpu_count']} CPUs (load average "
             f"{load['start']:.2f} at the start, {load['end']:.2f} at the end).", "",
             "| family | cases | internal errors | exit 0 with null | lost or mixed | hangs | "
             "silently accepted | other findings | time (s) | outcomes |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for family, row in summary["families"].items():
        statuses = ", ".join(f"{k} {v}" for k, v in row["by_status"].items())
        lines.append(f"| {family} | {row['cases']} | {row['internal_errors']} | "
                     f"{row['exit0_null']} | {row['lost_or_mixed']} | {row['hangs']} | "
                     f"{row['silently_accepted']} | {row['other_findings']} "
                     f"| {row['seconds']:.0f} | {statuses} |")
    feature = summary.get("live_token_feature")
    lines += ["", "The live server's token, Host and Origin checks were "
              + ("present and asserted." if feature else
                 "absent (foreign requests counted as served, not asserted)."
                 if feature is not None else "not tried.")]
    for family, why in summary.get("skipped", {}).items():
        lines.append(f"Skipped {family}: {why}.")
    if summary["failures"]:
        lines += ["", "## Findings", ""]
        lines += [f"- {f['family']} / {f['status']}: {f['change'][:100]} — {f['detail'][:200]}"
                  for f in summary["failures"]]
    return "\n".join(lines) + "\n"


def _bundled_examples() -> Path:
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidate = parent / "examples"
        if (candidate / "search-ellipse.yaml").exists():
            return candidate
    raise HapticframeError("the examples directory was not found: pass it from a checkout")
