"""The fuzz suite on a sample: every mutant of the examples is refused at validate with located
issues, or runs to a clean end (``hapticframe bench fuzz`` runs 320)."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

from hapticframe_bench._fuzz import (
    CATEGORIES,
    Mutant,
    check_mutant,
    generate_mutants,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_mutants_cover_every_category_and_are_seeded() -> None:
    mutants = generate_mutants(EXAMPLES, 40, seed=3)
    assert len(mutants) == 40
    assert {m.category for m in mutants} == set(CATEGORIES)
    again = generate_mutants(EXAMPLES, 40, seed=3)
    assert [m.change for m in mutants] == [m.change for m in again]


#: The sample's size: each mutant is a test of its own, so that no one test runs long (the
#: few that validate run the example, capped, for seconds).
SAMPLE = 120


@functools.cache
def _sample() -> tuple[Mutant, ...]:
    return tuple(generate_mutants(EXAMPLES, SAMPLE, seed=11))


@pytest.mark.parametrize("index", range(SAMPLE))
def test_a_sample_of_mutants_is_refused_or_runs_cleanly(tmp_path: Path, index: int) -> None:
    mutant = _sample()[index]
    # One movement is enough to see an accepted mutant run to a clean end (the bench runs 3).
    outcome = check_mutant(mutant, tmp_path / "m", max_movements=1)
    failures = [] if outcome.ok else [
        (mutant.example, mutant.change, outcome.status, outcome.detail)]
    assert not failures, failures


@pytest.mark.parametrize(("data", "status"), [
    ({"schema_version": 1, "name": "x", "seed": 1}, "refused"),  # nothing to run: refused
])
def test_the_checker_tells_refusals(tmp_path: Path, data: dict, status: str) -> None:
    outcome = check_mutant(Mutant("t.yaml", "structure", "t", data, False), tmp_path)
    assert outcome.status == status and outcome.ok


def test_the_checker_catches_an_internal_error(tmp_path: Path, monkeypatch) -> None:
    import hapticframe_bench._fuzz as fuzz

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(fuzz, "validate_file", broken)
    outcome = check_mutant(Mutant("t.yaml", "number", "t", {}, False), tmp_path)
    assert outcome.status == "internal_error" and not outcome.ok
