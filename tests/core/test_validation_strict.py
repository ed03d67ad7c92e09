"""Issue 16 §5: no quiet lax coercions of seeds, counts and names; warnings are printed.

``seed: true`` is not 1, ``seed: !!str 7`` is not 7, and a NUL in ``name`` is refused: exit 2
at ``validate``, located. Warnings (legal but suspicious) go to stderr as ``warning:``
lines located like errors, from ``validate`` and from ``run``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticframe.cli._cli import main

HEAD = "schema_version: 1\nname: strict\n"
BODY = "sensors:\n  - {id: wrist, type: trace-recording, config: {demo: true}}\n"


def _validate(tmp_path: Path, text: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    path = tmp_path / "strict.yaml"
    path.write_text(text, encoding="utf-8")
    status = main(["validate", str(path)])
    return status, capsys.readouterr().err


@pytest.mark.parametrize("seed", ["true", "!!str 7", "'7'", "7.0", "-1", ".nan", "2e19"])
def test_a_seed_that_is_no_plain_integer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], seed: str
) -> None:
    status, err = _validate(tmp_path, f"{HEAD}seed: {seed}\n{BODY}", capsys)
    assert status == 2 and "strict.yaml:3: seed:" in err, err
    assert "internal error" not in err


def test_a_plain_seed_is_accepted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _validate(tmp_path, f"{HEAD}seed: 7\n{BODY}", capsys)[0] == 0


@pytest.mark.parametrize("name", [r'"a\0b"', r'"two\nlines"', r'"bell\a"', "x" * 201, "''"])
def test_a_name_with_control_characters_or_too_long(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    status, err = _validate(tmp_path, f"schema_version: 1\nname: {name}\nseed: 1\n{BODY}",
                            capsys)
    assert status == 2 and "strict.yaml:2: name:" in err, err
    assert "internal error" not in err


def test_a_description_with_a_nul(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, err = _validate(tmp_path, f'{HEAD}seed: 1\ndescription: "x\\0"\n{BODY}', capsys)
    assert status == 2 and "description:" in err and "control characters" in err


@pytest.mark.parametrize("value", ["true", "'50'", "5.5"])
def test_a_count_that_is_no_integer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str
) -> None:
    status, err = _validate(tmp_path, f"{HEAD}seed: 1\n{BODY}run:\n  max_reads: {value}\n",
                            capsys)
    assert status == 2 and "run.max_reads:" in err, err


@pytest.mark.parametrize("cid", [r'"arm\0"', r'"arm\n"', "a" * 65])
def test_an_id_with_control_characters_or_too_long(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], cid: str
) -> None:
    text = f"{HEAD}seed: 1\nsensors:\n  - {{id: {cid}, type: trace-recording, " \
           "config: {demo: true}}\n"
    status, err = _validate(tmp_path, text, capsys)
    assert status == 2 and "sensors[0].id: an id is a letter" in err, err


WARNED = """\
schema_version: 1
name: warned
seed: 1
sensors:
  - {id: wrist, type: trace-recording, config: {demo: true}}
maps:
  - id: idle
    type: occupancy-grid
"""


def test_validate_prints_warnings_located(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status, err = _validate(tmp_path, WARNED, capsys)
    assert status == 0
    line = next(x for x in err.splitlines() if x.startswith("warning:"))
    assert line.startswith(f"warning: {tmp_path / 'strict.yaml'}:7: maps[0].inputs: ")
    assert "never updated" in line


def test_run_prints_warnings_before_it_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "warned.yaml"
    path.write_text(WARNED, encoding="utf-8")
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    # --out is a regular file: the run is refused after validation, the warning printed.
    assert main(["run", str(path), "--out", str(blocker), "--quiet"]) == 2
    assert "warning: " + f"{path}:7: maps[0].inputs:" in capsys.readouterr().err
