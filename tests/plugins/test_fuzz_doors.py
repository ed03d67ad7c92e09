"""The fuzz families of issue 36 on a sample: hostile tables, layouts, HDF5 files and
``.npz`` artifacts are refused located, intact ones read, inputs never changed (the bench
runs 100 of each); and the classifier counts a hang and a hostile file accepted."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

pytest.importorskip("h5py")
pytest.importorskip("openpyxl")

from hapticframe_bench._fuzz_common import Case
from hapticframe_bench._fuzz_doors import (
    ARTIFACT_KINDS,
    HDF5_KINDS,
    TABLE_KINDS,
    check_door_case,
    generate_door_cases,
    run_forked,
)
from hapticframe_bench._fuzz_families import tally

pytestmark = pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")


@pytest.mark.parametrize(("family", "kinds", "take"), [
    ("hdf5", HDF5_KINDS, None), ("artifacts", ARTIFACT_KINDS, None),
    ("tables", TABLE_KINDS, {"none", "long_cell", "fifo", "far_cell", "dtd", "h5_external",
                             "tiny_rate", "digits"}),
])
def test_every_kind_is_refused_located_or_read(tmp_path: Path, family: str, kinds: tuple,
                                               take: set[str] | None) -> None:
    cases = [c for c in generate_door_cases(family, len(kinds), seed=5)
             if take is None or c.kind in take]
    outcomes = [check_door_case(case, tmp_path / f"c{k}") for k, case in enumerate(cases)]
    bad = [(o.case.change, o.status, o.detail) for o in outcomes if not o.ok]
    assert not bad, bad
    by_kind = {o.case.kind: o.status for o in outcomes}
    assert by_kind["none"] == "ran"
    hostile = [o for o in outcomes if o.case.data["expect"] == "hostile"]
    assert hostile and all(o.status == "refused" for o in hostile)
    assert tally(outcomes, 0.0)["silently_accepted"] == 0


def test_a_hang_and_an_accepted_hostile_file_are_findings(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    started = time.perf_counter()
    assert run_forked(lambda: (time.sleep(30), (0, ""))[1], timeout_s=0.5)[0] == "timeout"
    assert time.perf_counter() - started < 10
    assert run_forked(lambda: (2, "error: x"))[1:] == (2, "error: x")
    case = Case("artifacts", "nan_member", "library nan", {
        "target": "library", "expect": "hostile", "seed": 1, "fraction": 0.5, "bits": 1,
        "variant": 0})
    import hapticframe_mpm_sand

    monkeypatch.setattr(hapticframe_mpm_sand, "load_library", lambda path: None)
    outcome = check_door_case(case, tmp_path / "c")
    assert outcome.status == "accepted_invalid" and not outcome.ok
    assert tally([outcome], 0.0)["silently_accepted"] == 1
