"""The families of ``hapticframe bench fuzz`` beyond the examples' mutants: ``recordings``,
``writers``, ``faults``, ``bags`` and ``live`` (issue 26), and ``tables``, ``hdf5`` and
``artifacts`` (issue 36: :mod:`hapticframe_bench._fuzz_doors`), each a generator of seeded
cases and a checker; this module makes their fixtures once and runs them in turn."""

from __future__ import annotations

import importlib.util
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hapticframe_bench._fuzz_common import Case, Outcome

__all__ = ["FAMILIES", "run_families", "tally"]

FAMILIES = ("recordings", "writers", "faults", "bags", "live", "tables", "hdf5", "artifacts")
#: The share of fault cases whose accepted schedules are also run (each run takes seconds).
FAULT_RUNS_PER_CASE = 0.1

#: The three counts the issue asks to be zero, and which statuses count for each.
COUNTED = {
    "internal_errors": ("internal_error",),
    "exit0_null": ("null_result", "null_metrics", "no_metrics"),
    "lost_or_mixed": ("lost_or_mixed",),
    "hangs": ("timeout",),
    "silently_accepted": ("accepted_invalid",),
}


def tally(outcomes: list[Outcome] | list[Any], seconds: float) -> dict[str, Any]:
    """A family's line of the report: cases, statuses, the three counts, other findings."""
    by_status: dict[str, int] = {}
    for o in outcomes:
        by_status[o.status] = by_status.get(o.status, 0) + 1
    counted = {name: sum(by_status.get(s, 0) for s in statuses)
               for name, statuses in COUNTED.items()}
    counted_statuses = {s for statuses in COUNTED.values() for s in statuses}
    other = sum(1 for o in outcomes if not o.ok and o.status not in counted_statuses)
    return {"cases": len(outcomes), "by_status": dict(sorted(by_status.items())),
            **counted, "other_findings": other, "seconds": round(seconds, 1)}


def run_families(workdir: Path, examples: Path, count: int, seed: int,
                 echo: Callable[[str], None],
                 families: tuple[str, ...] = FAMILIES) -> tuple[dict[str, list[Outcome]],
                                                                dict[str, Any]]:
    """Run ``count`` cases of each of ``families``; returns the outcomes by family and
    notes (the fixtures, whether the live server had its token feature, what was skipped)."""
    from hapticframe_bench._fuzz_records import make_record_fixtures

    notes: dict[str, Any] = {"skipped": {}}
    results: dict[str, list[Outcome]] = {}
    fixtures = make_record_fixtures(workdir / "fixtures", examples) \
        if {"recordings", "writers", "live"} & set(families) else None
    for family in families:
        started = time.perf_counter()
        cases, check, close = _family(family, count, seed, workdir, examples, fixtures, notes)
        outcomes: list[Outcome] = []
        try:
            for k, case in enumerate(cases):
                outcome = check(case, workdir / family / f"c{k:04d}")
                outcomes.append(outcome)
                mark = "ok  " if outcome.ok else "FAIL"
                echo(f"[{family} {k + 1:>4}/{len(cases)}] {mark} {outcome.status:<15} "
                     f"{case.change[:80]}"
                     + (f" -> {outcome.detail[:120]}" if outcome.detail and not outcome.ok
                        else ""))
        finally:
            close()
        results[family] = outcomes
        notes.setdefault("seconds", {})[family] = time.perf_counter() - started
    return results, notes


def _nothing() -> None:
    return None


def _family(family: str, count: int, seed: int, workdir: Path, examples: Path,
            fixtures: Any, notes: dict[str, Any]) -> tuple[
                list[Case], Callable[[Case, Path], Outcome], Callable[[], None]]:
    if family == "recordings":
        from hapticframe_bench._fuzz_records import check_record_case, generate_record_cases

        return (generate_record_cases(count, seed),
                lambda case, where: check_record_case(case, where, fixtures), _nothing)
    if family == "writers":
        from hapticframe_bench._fuzz_writers import check_writer_case, generate_writer_cases

        return (generate_writer_cases(count, seed),
                lambda case, where: check_writer_case(case, where, fixtures), _nothing)
    if family == "faults":
        from hapticframe_bench._fuzz_faults import check_fault_case, generate_fault_cases

        budget = [max(1, round(count * FAULT_RUNS_PER_CASE))]
        notes["fault_runs_cap"] = budget[0]

        def check_fault(case: Case, where: Path) -> Outcome:
            outcome = check_fault_case(case, where, run=budget[0] > 0)
            if outcome.status not in ("refused", "accepted", "unlocated", "accepted_invalid",
                                      "internal_error"):
                budget[0] -= 1  # it ran
            return outcome

        return generate_fault_cases(count, seed, examples), check_fault, _nothing
    if family == "bags":
        if importlib.util.find_spec("rosbags") is None:
            notes["skipped"]["bags"] = "rosbags is not installed: pip install 'hapticframe[bags]'"
            return [], lambda case, where: Outcome(case, "skipped", True), _nothing
        from hapticframe_bench._fuzz_bags import check_bag_case, generate_bag_cases, write_bags

        bags = write_bags(workdir / "bags", seed)
        return (generate_bag_cases(count, seed),
                lambda case, where: check_bag_case(case, where, bags), _nothing)
    if family == "live":
        if importlib.util.find_spec("aiohttp") is None:
            notes["skipped"]["live"] = "aiohttp is not installed: pip install 'hapticframe[live]'"
            return [], lambda case, where: Outcome(case, "skipped", True), _nothing
        from hapticframe_bench._fuzz_live import (
            check_live_case,
            generate_live_cases,
            start_view,
            token_feature_present,
        )

        target = start_view(fixtures.base, workdir / "live")
        notes["live_token_feature"] = token_feature_present(target)
        return (generate_live_cases(count, seed),
                lambda case, where: check_live_case(case, target), target.stop)
    if family in ("tables", "hdf5", "artifacts"):
        needs = {"tables": ("openpyxl", "h5py"), "hdf5": ("h5py",), "artifacts": ()}[family]
        missing = [m for m in needs if importlib.util.find_spec(m) is None]
        if missing or not hasattr(os, "fork"):
            notes["skipped"][family] = (f"{', '.join(missing)} not installed: pip install "
                                        "'hapticframe[tables]'" if missing else
                                        "needs os.fork (each case runs in a forked child)")
            return [], lambda case, where: Outcome(case, "skipped", True), _nothing
        from hapticframe_bench._fuzz_doors import check_door_case, generate_door_cases

        return generate_door_cases(family, count, seed), check_door_case, _nothing
    raise ValueError(f"no fuzz family {family!r}")
