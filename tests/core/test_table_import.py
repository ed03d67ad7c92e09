"""``hapticframe import``: tables (xlsx sheets, CSV files, HDF5 groups) by a layout file,
round-tripped against an independent read of the file, and bad tables refused, located."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.record._recording import read_recording
from hapticframe.record._tables import column_letters

openpyxl = pytest.importorskip("openpyxl")

LAYOUT = """\
schema_version: 1
name: small
sensor: tactile
rate_hz: 10.0
channels:
  force: {lines: [1, 2, 3, 4], shape: [2, 2], unit: "1"}
labels:
  side_class: {line: 6, classes: [left, right]}
  distance_mm: {line: 7, unit: mm}
position: {lines: [8, 9, 10], unit: m}
"""


def _sheet_rows(rng: np.random.Generator, steps: int) -> list[list[Any]]:
    rows: list[list[Any]] = [rng.random(steps).tolist() for _ in range(4)]
    rows.append([None] * steps)  # row 5 is empty, as in the real workbook
    rows.append([int(rng.integers(2))] * steps)
    rows.append(np.linspace(100.0, 10.0, steps).tolist())
    y = -0.4 - np.arange(steps) * 1e-3
    rows += [[-0.05] * steps, y.tolist(), [0.05] * steps]
    return rows


def _workbook(path: Path, sheets: dict[str, list[list[Any]]]) -> None:
    book = openpyxl.Workbook()
    book.remove(book.active)
    for name, rows in sheets.items():
        sheet = book.create_sheet(name)
        for row in rows:
            sheet.append(row)
    book.save(path)


@pytest.fixture
def layout(tmp_path: Path) -> Path:
    path = tmp_path / "layout.yaml"
    path.write_text(LAYOUT)
    return path


def _independent(path: Path) -> dict[str, np.ndarray]:
    """The workbook read with openpyxl alone: rows 1-4, 6, 7, 8-10 of every sheet."""
    book = openpyxl.load_workbook(path, data_only=True)
    force, side, distance, position = [], [], [], []
    for sheet in book.worksheets:
        rows = [[c.value for c in row] for row in sheet.iter_rows()]
        n = len([v for v in rows[0] if v is not None])
        force.append(np.array([r[:n] for r in rows[:4]], float).T.reshape(n, 2, 2))
        side.append(np.array(rows[5][:n], float))
        distance.append(np.array(rows[6][:n], float))
        position.append(np.array([r[:n] for r in rows[7:10]], float).T)
    return {"force": np.concatenate(force), "side_class": np.concatenate(side),
            "distance_mm": np.concatenate(distance), "position": np.concatenate(position)}


def test_xlsx_round_trip_into_both_recordings(tmp_path: Path, layout: Path) -> None:
    rng = np.random.default_rng(1)
    book = tmp_path / "trials.xlsx"
    _workbook(book, {"a": _sheet_rows(rng, 7), "b": _sheet_rows(rng, 5)})
    out = tmp_path / "out"
    assert main(["import", str(book), "--layout", str(layout), "--out", str(out)]) == 0
    truth = _independent(book)
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        np.testing.assert_array_equal(trace["sensor/tactile/force"], truth["force"])
        np.testing.assert_array_equal(trace["sensor/tactile/side_class"], truth["side_class"])
        np.testing.assert_array_equal(trace["sensor/tactile/distance_mm"], truth["distance_mm"])
        np.testing.assert_array_equal(trace["robot/tool/position_m"], truth["position"])
        assert str(trace["sensor/tactile/distance_mm/unit"]) == "mm"
        np.testing.assert_array_equal(trace["robot/tool/movement_index"], [0] * 7 + [1] * 5)
        t = trace["sensor/tactile/timestamps_s"]
        np.testing.assert_allclose(np.diff(t[:7]), 0.1)
        assert t[7] - t[6] == pytest.approx(1.0)  # the gap between trials
        assert list(trace["import/trial_names"]) == ["a", "b"]
    # The mcap holds the same samples, with units and rates.
    messages = read_recording(out / "run.mcap")["/sensor/tactile"]
    forces = np.concatenate([np.asarray(m["channels"]["force"], float) for _, m in messages])
    np.testing.assert_array_equal(forces, truth["force"])
    assert messages[0][1]["units"]["distance_mm"] == "mm"
    record = json.loads((out / "import.json").read_text())
    assert record["status"] == "ok" and record["steps"] == [7, 5]


def test_the_trace_recording_sensor_replays_an_import(tmp_path: Path, layout: Path) -> None:
    from hapticframe_recording._replay import load_recording

    rng = np.random.default_rng(2)
    book = tmp_path / "trials.xlsx"
    _workbook(book, {"s1": _sheet_rows(rng, 6), "s2": _sheet_rows(rng, 4)})
    assert main(["import", str(book), "--layout", str(layout), "--out",
                 str(tmp_path / "o")]) == 0
    recording = load_recording(tmp_path / "o", channels=("force", "side_class"))
    assert recording.trial_bounds() == [(0, 6), (6, 10)]
    assert recording.info["force"].shape == (2, 2)
    assert recording.info["force"].rate_hz == pytest.approx(10.0)


def test_csv_directory_and_hdf5_groups_read_as_the_workbook(tmp_path: Path,
                                                             layout: Path) -> None:
    h5py = pytest.importorskip("h5py")
    rng = np.random.default_rng(3)
    sheets = {"t1": _sheet_rows(rng, 6), "t2": _sheet_rows(rng, 8)}
    _workbook(tmp_path / "w.xlsx", sheets)
    (tmp_path / "csv").mkdir()
    with h5py.File(tmp_path / "t.h5", "w") as f:
        for name, rows in sheets.items():
            text = "\n".join(",".join("" if v is None else repr(v) for v in r) for r in rows)
            (tmp_path / "csv" / f"{name}.csv").write_text(text)
            f.create_group(name)["data"] = np.array(
                [[np.nan if v is None else v for v in r] for r in rows], float)
    # NaN rows (empty in the sheet) are not read by the layout, so they are no problem.
    outs = {}
    for source in ("w.xlsx", "csv", "t.h5"):
        out = tmp_path / f"out-{source}"
        assert main(["import", str(tmp_path / source), "--layout", str(layout),
                     "--out", str(out)]) == 0
        with np.load(out / "trace.npz", allow_pickle=False) as trace:
            outs[source] = {k: trace[k] for k in trace.files if not k.endswith("unit")}
    # openpyxl writes a float with 16 significant digits: the workbook is 1 ulp off.
    for source in ("csv", "t.h5"):
        for key, value in outs["w.xlsx"].items():
            if value.dtype.kind == "f":
                np.testing.assert_allclose(outs[source][key], value, rtol=1e-15, err_msg=key)
            else:
                np.testing.assert_array_equal(outs[source][key], value, err_msg=key)


@pytest.mark.parametrize(("edit", "located", "says"), [
    (lambda rows: rows[5].__setitem__(2, "left"), "sheet 'bad', row 6, column 3 (C)",
     "'left' is not a number"),
    (lambda rows: rows[5].__setitem__(1, 2), "sheet 'bad', row 6, column 2 (B)",
     "2 is not a class index 0..1"),
    (lambda rows: rows[6].__setitem__(4, None), "sheet 'bad', row 7, column 5 (E)",
     "distance_mm: an empty cell is not a number"),
    (lambda rows: rows[8].pop(), "sheet 'bad', row 9, column 6 (F)",
     "position y: an empty cell"),
    (lambda rows: rows[2].append(0.5), "sheet 'bad', row 3, column 7 (G)",
     "past the trial's last step"),
    (lambda rows: rows[1].__setitem__(0, "nan"), "sheet 'bad', row 2, column 1 (A)",
     "force[1]: nan is not finite"),
])
def test_a_bad_table_is_refused_located_before_anything_is_written(
        tmp_path: Path, layout: Path, capsys: Any, edit: Any, located: str, says: str) -> None:
    rng = np.random.default_rng(4)
    rows = _sheet_rows(rng, 6)
    edit(rows)
    book = tmp_path / "trials.xlsx"
    _workbook(book, {"good": _sheet_rows(rng, 6), "bad": rows})
    out = tmp_path / "out"
    assert main(["import", str(book), "--layout", str(layout), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{book}, {located}" in err and says in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_a_bad_layout_is_located_by_line(tmp_path: Path, capsys: Any) -> None:
    bad = tmp_path / "layout.yaml"
    bad.write_text(LAYOUT.replace("shape: [2, 2]", "shape: [3, 2]").replace(
        "rate_hz: 10.0", "rate_hz: -1"))
    book = tmp_path / "t.xlsx"
    _workbook(book, {"a": _sheet_rows(np.random.default_rng(5), 4)})
    assert main(["import", str(book), "--layout", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:4: rate_hz:" in err and "shape [3, 2] holds 6 values" in err, err
    assert not (tmp_path / "o").exists()


def test_an_empty_sheet_and_an_unknown_file_type(tmp_path: Path, layout: Path,
                                                 capsys: Any) -> None:
    book = tmp_path / "t.xlsx"
    _workbook(book, {"empty": [[None]]})
    assert main(["import", str(book), "--layout", str(layout), "--out", str(tmp_path / "o")]) == 2
    assert "sheet 'empty': row 1 (force[0]) holds no steps" in capsys.readouterr().err
    (tmp_path / "t.ods").write_text("x")
    assert main(["import", str(tmp_path / "t.ods"), "--layout", str(layout),
                 "--out", str(tmp_path / "o")]) == 2
    assert "unknown table type '.ods'" in capsys.readouterr().err


def test_column_letters() -> None:
    assert [column_letters(c) for c in (1, 26, 27, 52, 703)] == ["A", "Z", "AA", "AZ", "AAA"]
