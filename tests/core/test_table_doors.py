"""``hapticframe import`` refuses hostile tables and layouts (issue 36 §1): each case is a
small generated file that once gave an internal error, a hang, replaced data or an exit 0,
and must now be refused with exit 2, located at file, table, row and column (or the
layout's line), with nothing written."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.cli._cli import main

LAYOUT = """\
schema_version: 1
name: doors
rate_hz: 10.0
channels:
  force: {lines: [1, 2], unit: N}
labels:
  side: {line: 3, classes: [left, right]}
position: {lines: [4, 5, 6], unit: m}
"""
STEPS = 5


def _rows(steps: int = STEPS) -> list[list[Any]]:
    rng = np.random.default_rng(0)
    return [rng.random(steps).tolist(), rng.random(steps).tolist(), [0, 1, 0, 1, 0][:steps],
            [0.1] * steps, np.linspace(0.0, 0.4, steps).tolist(), [-0.02] * steps]


def _csv(path: Path, rows: list[list[Any]]) -> Path:
    path.write_text("\n".join(",".join(str(v) for v in row) for row in rows) + "\n")
    return path


def _layout(tmp_path: Path, text: str = LAYOUT) -> Path:
    path = tmp_path / "layout.yaml"
    path.write_text(text)
    return path


def _refused(capsys: Any, tmp_path: Path, table: Path, layout: Path) -> str:
    out = tmp_path / "out"
    code = main(["import", str(table), "--layout", str(layout), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "internal error" not in err and "Traceback" not in err, err
    assert not out.exists()
    return err


def test_a_good_table_still_imports(tmp_path: Path) -> None:
    table = _csv(tmp_path / "t.csv", _rows())
    assert main(["import", str(table), "--layout", str(_layout(tmp_path)), "--out",
                 str(tmp_path / "out")]) == 0
    with np.load(tmp_path / "out" / "trace.npz") as trace:
        np.testing.assert_allclose(trace["sensor/tactile/force"][:, 0], _rows()[0])
        np.testing.assert_allclose(trace["sensor/tactile/timestamps_s"], np.arange(5) / 10)


# --- the layout -------------------------------------------------------------------------

@pytest.mark.parametrize(("edit", "says"), [
    (("rate_hz: 10.0", "rate_hz: 1.0e-320"), "rate_hz"),
    (("rate_hz: 10.0", "rate_hz: 1.0e-9"), "rate_hz"),
    (("unit: N}", "unit: N, shape: [-1, -2]}"), "shape"),
    (("unit: N}", "unit: N, shape: [1, 2, 1]}"), "shape"),
    (("unit: N}", "unit: N, shape: [2, 1]}"), "shape"),
    (("  force:", "  timestamps_s:"), "timestamps_s"),
    (("  side:", "  timestamps_s:"), "timestamps_s"),
    (("  side:", "  position_m:"), "position_m"),
    (("  force:", "  movement_index:"), "movement_index"),
    (("{line: 3,", "{line: 2,"), "line 2"),
    (("lines: [4, 5, 6]", "lines: [4, 4, 6]"), "line 4"),
    (("lines: [4, 5, 6]", "lines: [4, 5, 3]"), "line 3"),
    (("lines: [4, 5, 6]", "lines: [1, 5, 6]"), "line 1"),
    (("classes: [left, right]", "classes: [left, left]"), "left"),
    (("  force:", "  f" + "o" * 1000 + ":"), "characters"),
])
def test_a_layout_that_cannot_be_read_truly_is_refused_at_its_line(
        tmp_path: Path, capsys: Any, edit: tuple[str, str], says: str) -> None:
    old, new = edit
    assert old in LAYOUT
    layout = _layout(tmp_path, LAYOUT.replace(old, new, 1))
    table = _csv(tmp_path / "t.csv", _rows())
    err = _refused(capsys, tmp_path, table, layout)
    assert f"{layout}:" in err and says in err, err
    assert len(err) < 3000, "the message echoes the whole long name"


@pytest.mark.parametrize("cell", ["1_0", "\u0661\u0662", "\uff11\uff12", "0x10", " 1e3_0",
                                  "infinity", "1e999"])
def test_numbers_are_ascii_decimal_as_the_layout_says(tmp_path: Path, capsys: Any,
                                                      cell: str) -> None:
    rows = _rows()
    rows[1][3] = cell
    table = _csv(tmp_path / "t.csv", rows)
    err = _refused(capsys, tmp_path, table, _layout(tmp_path))
    assert "row 2, column 4 (D)" in err, err


def test_plain_decimal_forms_are_read(tmp_path: Path) -> None:
    rows = _rows()
    rows[0][:5] = ["1", "-2.5", "+.5", "3.", "4E-2"]
    table = _csv(tmp_path / "t.csv", rows)
    assert main(["import", str(table), "--layout", str(_layout(tmp_path)), "--out",
                 str(tmp_path / "out")]) == 0
    with np.load(tmp_path / "out" / "trace.npz") as trace:
        np.testing.assert_array_equal(trace["sensor/tactile/force"][:, 0],
                                      [1, -2.5, 0.5, 3.0, 0.04])


# --- CSV --------------------------------------------------------------------------------

def test_a_csv_cell_past_the_field_limit_in_an_unused_row(tmp_path: Path,
                                                          capsys: Any) -> None:
    rows = _rows() + [[], ["x" * 200_000]]
    table = _csv(tmp_path / "t.csv", rows)
    err = _refused(capsys, tmp_path, table, _layout(tmp_path))
    assert str(table) in err and "row 8" in err and "column 1" in err, err


def _import_in_child(tmp_path: Path, table: Path, layout: Path) -> subprocess.CompletedProcess[
        str]:
    # A child process, so that a regression that blocks on a FIFO fails instead of hanging.
    env = {**os.environ, "HAPTICFRAME_MIN_FREE_MB": "1"}
    try:
        return subprocess.run([sys.executable, "-m", "hapticframe", "import", str(table),
                               "--layout", str(layout), "--out", str(tmp_path / "out")],
                              capture_output=True, text=True, timeout=60, env=env,
                              stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("import blocked on a FIFO")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("in_directory", [False, True])
def test_a_fifo_given_as_a_csv_table_is_refused_at_once(tmp_path: Path,
                                                        in_directory: bool) -> None:
    folder = tmp_path / "tables"
    folder.mkdir()
    _csv(folder / "a.csv", _rows())
    fifo = folder / "b.csv"
    os.mkfifo(fifo)
    done = _import_in_child(tmp_path, folder if in_directory else fifo, _layout(tmp_path))
    assert done.returncode == 2, done.stderr
    assert "b.csv" in done.stderr and "FIFO" in done.stderr, done.stderr
    assert "internal error" not in done.stderr


# --- xlsx -------------------------------------------------------------------------------

def _workbook(path: Path, rows: list[list[Any]], far: str | None = None) -> Path:
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "s1"
    for row in rows:
        sheet.append(row)
    if far is not None:
        sheet[far] = 1.0
    book.save(path)
    return path


def _rewrite_sheet(path: Path, edit: Any) -> None:
    """Rewrite the first worksheet's XML of the workbook at ``path`` with ``edit``."""
    with zipfile.ZipFile(path) as src:
        members = {info.filename: src.read(info) for info in src.infolist()}
    name = "xl/worksheets/sheet1.xml"
    members[name] = edit(members[name].decode("utf-8")).encode("utf-8")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as dst:
        for member, data in members.items():
            dst.writestr(member, data)


@pytest.mark.parametrize(("far", "dimension", "says"), [
    ("XFD1048576", True, "A1:XFD1048576"), ("XFD1048576", False, "row 1048576, column 16384"),
    ("ZZ500000", False, "row 500000, column 702 (ZZ)")])
def test_xlsx_cells_far_apart_are_refused_before_the_grid_is_built(
        tmp_path: Path, capsys: Any, far: str, dimension: bool, says: str) -> None:
    book = _workbook(tmp_path / "t.xlsx", _rows(), far=far)
    if not dimension:
        _rewrite_sheet(book, lambda xml: re.sub(r"<dimension [^>]*/>", "", xml))
    err = _refused(capsys, tmp_path, book, _layout(tmp_path))
    assert f"{book}, sheet 's1'" in err and says in err, err


def test_a_stray_cell_far_down_within_the_bound_still_imports(tmp_path: Path) -> None:
    # 1048576 rows x 5 columns is under MAX_CELLS: read (empty rows cost no cells).
    book = _workbook(tmp_path / "t.xlsx", _rows(), far="A1048576")
    _rewrite_sheet(book, lambda xml: re.sub(r"<dimension [^>]*/>", "", xml))
    assert main(["import", str(book), "--layout", str(_layout(tmp_path)), "--out",
                 str(tmp_path / "out")]) == 0


_ENTITY = '<?xml version="1.0"?>\n<!DOCTYPE worksheet [<!ENTITY e "0.5">]>\n'
_LAUGHS = ('<?xml version="1.0"?>\n<!DOCTYPE worksheet [<!ENTITY a "ha">'
           + "".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">'
                     for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "]>\n")


@pytest.mark.parametrize("doctype", [_ENTITY, _LAUGHS])
def test_xlsx_with_a_dtd_is_refused_before_it_is_parsed(tmp_path: Path, capsys: Any,
                                                        doctype: str) -> None:
    book = _workbook(tmp_path / "t.xlsx", _rows())

    def add_dtd(xml: str) -> str:
        body = re.sub(r"^<\?xml[^>]*\?>\s*", "", xml)
        return doctype + body.replace("<v>0</v>", "<v>&e;</v>" if "ENTITY e" in doctype
                                      else "<v>&i;</v>", 1)

    _rewrite_sheet(book, add_dtd)
    err = _refused(capsys, tmp_path, book, _layout(tmp_path))
    assert str(book) in err and "sheet1.xml" in err and "DOCTYPE" in err, err


# --- HDF5 -------------------------------------------------------------------------------

h5py_required = pytest.mark.skipif(
    __import__("importlib").util.find_spec("h5py") is None, reason="needs h5py")


def _h5(path: Path, build: Any = None, *, latest: bool = False) -> Path:
    import h5py

    with h5py.File(path, "w", libver="latest" if latest else "earliest") as f:
        f.create_group("t1")["data"] = np.array(_rows(), float)
        if build is not None:
            build(f)
    return path


@h5py_required
def test_a_good_hdf5_table_still_imports(tmp_path: Path) -> None:
    assert main(["import", str(_h5(tmp_path / "t.h5")), "--layout", str(_layout(tmp_path)),
                 "--out", str(tmp_path / "out")]) == 0


def _dangling(f: Any) -> None:
    import h5py

    f.create_group("t2")["data"] = h5py.SoftLink("/nowhere/data")


def _loop(f: Any) -> None:
    import h5py

    f["t2"] = h5py.SoftLink("/t3")
    f["t3"] = h5py.SoftLink("/t2")


def _missing_file(f: Any) -> None:
    import h5py

    f["t2"] = h5py.ExternalLink("missing.h5", "/t1")


def _itself(f: Any) -> None:
    import h5py

    f["t2"] = h5py.ExternalLink(f.filename, "/t2")


def _fill_value(f: Any) -> None:
    f.create_group("t2").create_dataset("data", shape=(10, 22_000_000), dtype="f8",
                                        fillvalue=1.0)


@h5py_required
@pytest.mark.parametrize(("build", "says"), [
    (_dangling, "t2"), (_loop, "t2"), (_missing_file, "t2"), (_itself, "t2"),
    (_fill_value, "220000000"),
])
def test_hostile_hdf5_tables_are_refused_located(tmp_path: Path, capsys: Any, build: Any,
                                                 says: str) -> None:
    table = _h5(tmp_path / "t.h5", build)
    err = _refused(capsys, tmp_path, table, _layout(tmp_path))
    assert str(table) in err and says in err, err


@h5py_required
def test_an_hdf5_table_with_a_flipped_bit_in_an_object_header(tmp_path: Path,
                                                              capsys: Any) -> None:
    table = _h5(tmp_path / "t.h5", latest=True)
    blob = bytearray(table.read_bytes())
    headers = [m.start() for m in re.finditer(b"OHDR", blob)]
    assert len(headers) >= 3  # the root, the group and the dataset
    blob[headers[1] + 4] ^= 0x04  # the group's header: its version byte
    table.write_bytes(bytes(blob))
    err = _refused(capsys, tmp_path, table, _layout(tmp_path))
    assert str(table) in err and "t1" in err, err


@h5py_required
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_an_hdf5_dataset_stored_in_a_fifo_is_refused_at_once(tmp_path: Path) -> None:
    import h5py

    fifo = tmp_path / "raw.bin"
    os.mkfifo(fifo)
    table = tmp_path / "t.h5"
    with h5py.File(table, "w") as f:
        f.create_group("t1").create_dataset("data", shape=(6, STEPS), dtype="f8",
                                            external=[(str(fifo), 0, 6 * STEPS * 8)])
    done = _import_in_child(tmp_path, table, _layout(tmp_path))
    assert done.returncode == 2, done.stderr
    assert str(table) in done.stderr and "outside the file" in done.stderr, done.stderr
