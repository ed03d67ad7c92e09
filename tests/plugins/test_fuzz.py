"""The fuzz suite on a sample: every mutant of the examples is refused at validate with located
issues, or runs to a clean end (``hapticframe bench fuzz`` runs 320); every case of the
families of issue 26 (damaged recordings and bags, concurrent writers, fault schedules, a
hostile live-page client) is refused with a located message or ends cleanly (the bench runs
100 of each)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import pytest

from hapticframe_bench._fuzz import (
    CATEGORIES,
    Mutant,
    check_mutant,
    generate_mutants,
)
from hapticframe_bench._fuzz_common import (
    Case,
    CommandResult,
    classify,
    compare_snapshots,
    json_has_null_number,
)
from hapticframe_bench._fuzz_common import Outcome as CaseOutcome
from hapticframe_bench._fuzz_families import tally

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


# --- the families of issue 26 ----------------------------------------------------------------
# Each family's sample is seeded and small (one case a test, a second or two each); the
# bench runs 100 of each (`hapticframe bench fuzz`).



@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Any:
    from hapticframe_bench._fuzz_records import make_record_fixtures

    return make_record_fixtures(tmp_path_factory.mktemp("fixtures"), EXAMPLES)


def test_the_classifier_tells_findings_from_clean_ends() -> None:
    case = Case("t", "k", "c")
    assert classify(case, CommandResult(1, "", "internal error: ValueError: x"), 0.0).status \
        == "internal_error"
    assert classify(case, CommandResult(1, "", "Traceback (most recent call last):\n"), 0.0
                    ).status == "internal_error"
    assert classify(case, CommandResult(2, "", "error: bad"), 0.0, names=("run.mcap",)
                    ).status == "unlocated"
    assert classify(case, CommandResult(2, "", "error: x/run.mcap is cut"), 0.0,
                    names=("run.mcap",)).status == "refused"
    assert classify(case, CommandResult(1, "", "error: cannot open x"), 0.0).status \
        == "failed_clean"
    assert classify(case, CommandResult(-1, "", "", timed_out=True), 0.0).status == "timeout"
    assert compare_snapshots({"a": "1", "b": "2", "c": "3"}, {"a": "1", "b": "9"}) == [
        "b rewritten", "c deleted"]


def test_a_null_result_is_caught(tmp_path: Path) -> None:
    path = tmp_path / "metrics.json"
    path.write_text('{"movements": NaN}', encoding="utf-8")
    assert "not strict JSON" in (json_has_null_number(path) or "")
    path.write_text('{"movements": null}', encoding="utf-8")
    assert json_has_null_number(path, ("movements",)) == "metrics.json: movements is None"
    path.write_text('{"movements": 3}', encoding="utf-8")
    assert json_has_null_number(path, ("movements",)) is None
    outcomes = [CaseOutcome(Case("t", "k", "c"), s, s == "ran")
                for s in ("ran", "null_result", "lost_or_mixed", "internal_error", "unlocated")]
    row = tally(outcomes, 1.0)
    assert (row["internal_errors"], row["exit0_null"], row["lost_or_mixed"],
            row["other_findings"]) == (1, 1, 1, 1)


def test_the_mcap_layout_finds_chunks_and_crcs(runs: Any) -> None:
    from hapticframe_bench._fuzz_records import mcap_layout

    layout = mcap_layout((runs.base / "run.mcap").read_bytes())
    assert layout["chunk"] and len(layout["chunk_crc"]) == len(layout["chunk"])
    assert len(layout["data_crc"]) == 1 and len(layout["summary_crc"]) == 1


RECORD_SAMPLE = 8


@pytest.mark.parametrize("index", range(RECORD_SAMPLE))
def test_a_sample_of_damaged_recordings(runs: Any, tmp_path: Path, index: int) -> None:
    from hapticframe_bench._fuzz_records import check_record_case, generate_record_cases

    case = generate_record_cases(RECORD_SAMPLE, seed=5)[index]
    outcome = check_record_case(case, tmp_path, runs)
    assert outcome.ok, (case.change, outcome.status, outcome.detail)


def test_a_recording_checker_sees_a_finished_run_changed(runs: Any, tmp_path: Path,
                                                         monkeypatch: Any) -> None:
    import hapticframe_bench._fuzz_records as records

    def destructive(args: list[str], **kwargs: Any) -> CommandResult:
        (Path(args[1]) / "trace.npz").unlink()  # what issue 26 found `report` doing
        return CommandResult(0, "", "")

    monkeypatch.setattr(records, "hapticframe_command", destructive)
    case = Case("recordings", "truncate", "t", {"command": "report", "seed": 1,
                                                "fraction": 0.5, "bits": 1})
    outcome = records.check_record_case(case, tmp_path, runs)
    assert outcome.status == "lost_or_mixed" and "trace.npz deleted" in outcome.detail


WRITER_SAMPLE = 9  # six locked, three tampered (the race, two runs at once, is the bench's)


@pytest.mark.parametrize("index", range(WRITER_SAMPLE))
def test_a_sample_of_concurrent_writers(runs: Any, tmp_path: Path, index: int) -> None:
    from hapticframe_bench._fuzz_writers import check_writer_case, generate_writer_cases

    case = generate_writer_cases(WRITER_SAMPLE, seed=5)[index]
    outcome = check_writer_case(case, tmp_path, runs)
    assert outcome.ok, (case.change, outcome.status, outcome.detail)


def test_the_fault_family_flags_what_a_device_cannot_have() -> None:
    from hapticframe_bench._fuzz_faults import cannot_have

    assert cannot_have("robotiq-ft300", [{"kind": "bad_crcc", "rate_hz": 1.0}])
    assert cannot_have("robotiq-ft300", [{"kind": "bus_overrun", "rate_hz": 1.0}])
    assert cannot_have("bno055", [{"kind": "stall", "at_s": float("nan")}])
    assert cannot_have("bno055", [{"kind": "stall", "rate_hz": 1e12}])
    assert cannot_have("dynamixel", [{"kind": "junk", "at_s": 1.0, "params": {"zz": 1}}])
    assert cannot_have("robotiq-ft300", [{"kind": "bad_crc", "rate_hz": 2.0}]) is None
    assert cannot_have("bno055", "standard") is None


def test_a_sample_of_fault_schedules_is_refused_located_or_accepted(tmp_path: Path) -> None:
    from hapticframe_bench._fuzz_faults import check_fault_case, generate_fault_cases

    cases = generate_fault_cases(40, seed=5, examples_dir=EXAMPLES)
    outcomes = [check_fault_case(case, tmp_path / f"c{k}", run=False)
                for k, case in enumerate(cases)]
    bad = [(o.case.change, o.status, o.detail) for o in outcomes if not o.ok]
    assert not bad, bad
    assert {o.status for o in outcomes} == {"refused", "accepted"}


def test_an_accepted_fault_schedule_runs_cleanly(tmp_path: Path) -> None:
    import yaml

    from hapticframe_bench._fuzz_faults import check_fault_case

    data = yaml.safe_load((EXAMPLES / "free-motion-ft300.yaml").read_text("utf-8"))
    faults = [{"kind": "bad_crc", "rate_hz": 3.0},
              {"kind": "stall", "at_s": 0.5, "duration_s": 0.05}]
    assert data["sensors"][0]["type"] == "robotiq-ft300"
    data["sensors"][0]["config"]["faults"] = faults
    case = Case("faults", "robotiq-ft300", "bad_crc and a stall",
                {"experiment": data, "device": "robotiq-ft300", "faults": faults})
    outcome = check_fault_case(case, tmp_path)
    assert outcome.status == "ran", outcome.detail


BAG_SAMPLE = 9  # one of each damage


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> Any:
    pytest.importorskip("rosbags")
    from hapticframe_bench._fuzz_bags import write_bags

    return write_bags(tmp_path_factory.mktemp("bags"))


@pytest.mark.parametrize("index", range(BAG_SAMPLE))
def test_a_sample_of_damaged_bags(bags: Any, tmp_path: Path, index: int) -> None:
    from hapticframe_bench._fuzz_bags import check_bag_case, generate_bag_cases

    case = generate_bag_cases(BAG_SAMPLE, seed=5)[index]
    outcome = check_bag_case(case, tmp_path, bags)
    assert outcome.ok, (case.change, outcome.status, outcome.detail)


def test_a_sample_of_hostile_live_clients(runs: Any, tmp_path: Path) -> None:
    pytest.importorskip("aiohttp")
    from hapticframe_bench._fuzz_live import (
        check_live_case,
        generate_live_cases,
        start_view,
        token_feature_present,
    )

    target = start_view(runs.base, tmp_path)
    try:
        present = token_feature_present(target)
        outcomes = [check_live_case(case, target) for case in generate_live_cases(16, seed=5)]
    finally:
        target.stop()
    bad = [(o.case.change, o.status, o.detail) for o in outcomes if not o.ok]
    if not present:
        # Before the server's checks of issue 26 §5 (branch `live`: token, Host, Origin, and
        # times that are not finite refused), a NaN time gives a frame of non-strict JSON:
        # the bench counts it as a finding; here it is the one finding tolerated.
        bad = [b for b in bad if b[1] != "null_result"]
    assert not bad, bad
    foreign = [o for o in outcomes if o.case.kind == "foreign"]
    assert foreign
    if present:  # only asserted where the server has its token, Host and Origin checks
        assert all(o.status == "refused" for o in foreign)


def test_the_bench_reports_each_family_in_json_and_markdown(tmp_path: Path) -> None:
    import json

    from hapticframe import BenchOptions
    from hapticframe_bench._fuzz import Outcome, run_fuzz

    lines: list[str] = []
    summary = run_fuzz(BenchOptions(out_dir=tmp_path, trials=4, seed=2, echo=lines.append),
                       examples_dir=EXAMPLES, families=("faults",),
                       check=lambda mutant, where: Outcome(mutant, "null_metrics", False))
    saved = json.loads((tmp_path / "fuzz.json").read_text(encoding="utf-8"))
    assert saved["families"]["examples"]["exit0_null"] == 4  # the stub's findings, counted
    assert saved["families"]["faults"]["cases"] == 4 and saved["cases"] == 8
    assert saved["exit0_null"] == 4 and summary["internal_errors"] == 0
    table = (tmp_path / "fuzz.md").read_text(encoding="utf-8")
    assert "| faults | 4 |" in table and "## Findings" in table
    assert any(line.startswith("[faults") for line in lines)
