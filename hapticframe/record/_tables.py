"""Tabular trial data (spreadsheets, CSV files, HDF5 groups) read by a declared layout.

A lab's table needs a layout file and no code. The layout (YAML or JSON, loaded safely by
:func:`hapticframe._config._load.load_file`) says along which axis time runs, which lines
(rows, or columns) of a table are which channel with its unit and shape, which are labels
(class indices or a quantity with a unit), which are the tool's position, and the nominal
sample rate. One trial is one table: a worksheet of an ``.xlsx`` workbook (openpyxl, the
``tables`` extra), one ``.csv`` file (a file, or a directory of them), or one group of an
HDF5 file holding a 2-D dataset (h5py). Line and step numbers in a layout and in every
message are 1-based, as a spreadsheet shows them.

Every table is checked against the layout before anything is built: a missing, empty,
non-numeric or non-finite cell, a label that is not a whole class index in range, a line
shorter or longer than the trial's steps, each is a :class:`TableError` (exit status 2) that
names the file, the table (sheet, CSV file or HDF5 group), the row and the column.
"""

from __future__ import annotations

import csv
import io
import math
import re
import stat
import zipfile
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hapticframe._config._load import load_file
from hapticframe._errors import ExperimentError, HapticframeError, Issue, bound_text
from hapticframe.bounded_io import (
    BoundedReadError,
    format_bytes,
    hdf5_child,
    hdf5_members,
    open_hdf5,
    open_regular,
    read_hdf5_dataset,
)

__all__ = [
    "MAX_CELLS",
    "MAX_TABLE_BYTES",
    "MAX_TABLE_ISSUES",
    "MIN_RATE_HZ",
    "RESERVED_NAMES",
    "ChannelLayout",
    "LabelLayout",
    "PositionLayout",
    "TableError",
    "TableLayout",
    "TableTrial",
    "column_letters",
    "load_layout",
    "read_trials",
]

#: Problems a :class:`TableError` lists before it stops looking.
MAX_TABLE_ISSUES = 20
#: Cells one import may read (about 100 MB of float64): a bound on what a file can cost.
MAX_CELLS = 12_000_000
#: Bytes of one CSV file, and of a workbook's XML once decompressed, read at most.
MAX_TABLE_BYTES = 1024**3
#: Names a layout may not give a channel or label: the recording's own arrays.
RESERVED_NAMES = ("timestamps_s", "position_m", "movement_index")
#: Slowest rate a layout may declare: one step per 1000 s (the step's length stays finite).
MIN_RATE_HZ = 1e-3
#: Longest channel or label name.
MAX_NAME_CHARS = 64

_NAME = r"^[a-z][a-z0-9_]*$"
# A number as a layout's tables write it: ASCII decimal digits with an optional sign,
# point and exponent (no '_' separators, no other scripts' digits, no hex); 'nan' and
# 'inf' are read so that they can be refused as not finite.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                      r"|[+-]?(?:nan|inf|infinity)", re.ASCII | re.IGNORECASE)


class TableError(HapticframeError):
    """A table does not match its layout; every message names file, table, row and column."""

    exit_code = 2

    def __init__(self, problems: Sequence[str], more: int = 0) -> None:
        self.problems = list(problems)
        lines = list(problems)
        if more:
            lines.append(f"…and {more} more problems")
        if len(problems) > 1:
            lines.insert(0, f"{len(problems) + more} problems in the tables")
        super().__init__("\n".join(lines))


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ChannelLayout(_Strict):
    """A sensor channel: its lines (one per element, row-major in ``shape``) and unit."""

    lines: tuple[int, ...] = Field(min_length=1, description="1-based rows (or columns).")
    unit: str = Field(min_length=1, description="Unit of the values ('1': dimensionless).")
    shape: tuple[int, ...] | None = Field(
        None, description="Per-sample shape; its product is the number of lines. None: "
        "one line is a scalar channel, several a vector.")

    @model_validator(mode="after")
    def _shape_fits(self) -> ChannelLayout:
        if min(self.lines) < 1:
            raise ValueError("lines are 1-based: the first row (or column) is 1")
        if len(set(self.lines)) != len(self.lines):
            raise ValueError(f"lines repeat: {list(self.lines)}")
        if self.shape is not None and any(n < 2 for n in self.shape):
            raise ValueError(f"shape {list(self.shape)}: every entry is a whole number of at "
                             "least 2 (an entry of 1 only pads the shape: leave it out; a "
                             "single line is a scalar channel without a shape)")
        if self.shape is not None and math.prod(self.shape) != len(self.lines):
            raise ValueError(f"shape {list(self.shape)} holds {math.prod(self.shape)} values, "
                             f"but {len(self.lines)} lines are given")
        return self

    def sample_shape(self) -> tuple[int, ...]:
        if self.shape is not None:
            return self.shape
        return () if len(self.lines) == 1 else (len(self.lines),)


class LabelLayout(_Strict):
    """A label line: class indices (``classes`` given) or a labelled quantity with a unit."""

    line: int = Field(ge=1, description="1-based row (or column).")
    unit: str = Field("1", min_length=1)
    classes: tuple[str, ...] | None = Field(
        None, min_length=2, description="Class names; the cells hold indices 0..k-1.")

    @model_validator(mode="after")
    def _distinct_classes(self) -> LabelLayout:
        if self.classes is not None:
            seen: set[str] = set()
            for name in self.classes:
                if name in seen:
                    raise ValueError(f"class {bound_text(name)!r} is named twice: each index "
                                     "needs its own name")
                seen.add(name)
        return self


class PositionLayout(_Strict):
    """The tool's position, three lines (x, y, z) in metres or millimetres."""

    lines: tuple[int, int, int]
    unit: Literal["m", "mm"] = "m"
    frame: str = Field("", description="What the coordinates are relative to.")


class TableLayout(_Strict):
    """Where a table keeps its channels, labels and positions (one trial per table)."""

    schema_version: Literal[1] = 1
    name: str = Field(min_length=1)
    sensor: str = Field("tactile", pattern=_NAME, description="Sensor id of the recording.")
    robot: str = Field("tool", pattern=_NAME, description="Robot id whose movement_index "
                       "numbers the trials.")
    time_along: Literal["columns", "rows"] = Field(
        "columns", description="'columns': one step per column, channels in rows.")
    first_step: int = Field(1, ge=1, description="1-based column (or row) of the first step.")
    rate_hz: float = Field(ge=MIN_RATE_HZ, le=1e6, allow_inf_nan=False,
                           description="Nominal sample rate (1e-3..1e6 Hz).")
    rate_note: str = Field("", description="Where the rate comes from (or the assumption).")
    channels: dict[str, ChannelLayout] = Field(min_length=1)
    labels: dict[str, LabelLayout] = Field(default_factory=dict)
    position: PositionLayout | None = None
    hdf5_dataset: str = Field("data", min_length=1,
                              description="Name of the 2-D dataset in each HDF5 group.")

    @model_validator(mode="after")
    def _names(self) -> TableLayout:
        names = list(self.channels) + list(self.labels)
        for name in names:
            if len(name) > MAX_NAME_CHARS:
                raise ValueError(f"a name of {len(name)} characters ({name[:40]!r}…"
                                 f"); names are at most {MAX_NAME_CHARS} characters")
            if not re.match(_NAME, name):
                raise ValueError(f"{name!r} is not a channel name (lowercase letters, digits "
                                 "and '_', starting with a letter)")
            if name in RESERVED_NAMES:
                raise ValueError(f"{name!r} is a name the recording uses for its own arrays "
                                 f"({', '.join(RESERVED_NAMES)}); rename the channel or label")
        if len(set(names)) != len(names):
            raise ValueError("a label has the name of a channel")
        self._lines_once()
        return self

    def _lines_once(self) -> None:
        """Every line is read as one thing only (a channel element, a label or an axis)."""
        seen: dict[int, str] = {}
        for line, what in self._line_uses():
            if line in seen:
                raise ValueError(f"line {line} is read as both {seen[line]} and {what}; "
                                 "each row (or column) holds one thing")
            seen[line] = what

    def _line_uses(self) -> list[tuple[int, str]]:
        uses: list[tuple[int, str]] = []
        for name, channel in self.channels.items():
            uses += [(line, f"{name}[{i}]" if len(channel.lines) > 1 else name)
                     for i, line in enumerate(channel.lines)]
        uses += [(label.line, name) for name, label in self.labels.items()]
        if self.position is not None:
            uses += [(line, f"position {axis}")
                     for axis, line in zip("xyz", self.position.lines, strict=True)]
        return uses

    def used_lines(self) -> dict[int, str]:
        """Every line the layout reads and what it is (for messages)."""
        return dict(self._line_uses())


def load_layout(path: str | Path) -> TableLayout:
    """Read and validate a layout file; ExperimentError (file, line, dotted path) if bad."""
    loaded = load_file(path)
    try:
        return TableLayout.model_validate(loaded.data)
    except ValidationError as exc:
        issues = []
        for error in exc.errors():
            dotted = ".".join(str(p) for p in error["loc"])
            issues.append(Issue(dotted, error["msg"], loaded.line_of(dotted)))
        raise ExperimentError(str(path), issues) from None
    except ValueError as exc:
        raise ExperimentError(str(path), [Issue("", str(exc))]) from None


@dataclass(frozen=True)
class TableTrial:
    """One trial read from one table.

    ``channels`` map names to ``(n, *shape)`` float64 arrays, ``labels`` to ``(n,)`` float64
    (class indices are whole numbers), ``position_m`` is ``(n, 3)`` metres or None.
    """

    name: str
    channels: Mapping[str, np.ndarray]
    labels: Mapping[str, np.ndarray]
    position_m: np.ndarray | None

    @property
    def steps(self) -> int:
        return int(next(iter(self.channels.values())).shape[0])


def column_letters(column: int) -> str:
    """A spreadsheet's name of a 1-based column (1 -> A, 27 -> AA)."""
    letters = ""
    while column > 0:
        column, rest = divmod(column - 1, 26)
        letters = chr(ord("A") + rest) + letters
    return letters


_Cells = list[list[Any]]


def _tables(path: Path, layout: TableLayout) -> Iterator[tuple[str, str, _Cells]]:
    """(kind of table, its name, its cells as rows) for each trial in ``path``."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise TableError([f"{path}: no such file or directory"]) from None
    except OSError as exc:
        raise TableError([f"{path}: cannot be read ({exc.strerror or exc})"]) from None
    if stat.S_ISDIR(mode):
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".csv")
        if not files:
            raise TableError([f"{path}: a directory of trials must hold .csv files; it has "
                              "none"])
        for file in files:
            yield "file", file.name, _read_csv(file)
        return
    suffix = path.suffix.lower()
    if suffix == ".xlsx":
        yield from _read_xlsx(path)
    elif suffix == ".csv":
        yield "file", path.name, _read_csv(path)
    elif suffix in (".h5", ".hdf5"):
        yield from _read_hdf5(path, layout.hdf5_dataset)
    else:
        raise TableError([f"{path}: unknown table type {suffix!r}; use .xlsx, .csv (a file or "
                          "a directory of them), .h5 or .hdf5"])


def _read_bounded(path: Path) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_TABLE_BYTES` (never blocks)."""
    try:
        with open_regular(path) as stream:
            raw = stream.read(MAX_TABLE_BYTES + 1)
    except FileNotFoundError:
        raise TableError([f"{path}: no such file"]) from None
    except (BoundedReadError, OSError) as exc:
        raise TableError([f"{path}: {exc}"]) from None
    if len(raw) > MAX_TABLE_BYTES:
        raise TableError([f"{path}: larger than {format_bytes(MAX_TABLE_BYTES)}; split the "
                          "trials into several files"])
    return raw


def _read_csv(path: Path) -> _Cells:
    raw = _read_bounded(path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise TableError([f"{path}: cannot be read as UTF-8 text ({exc})"]) from None
    reader = csv.reader(io.StringIO(text))
    rows: _Cells = []
    try:
        for row in reader:
            rows.append(list(row))
    except csv.Error as exc:
        row_number = len(rows) + 1
        lines = text.splitlines()
        column = _long_field_column(lines[reader.line_num - 1]) if 0 < reader.line_num <= len(
            lines) else None
        where = f"{path}, file {path.name!r}, row {row_number}"
        if column is not None:
            where += f", column {column} ({column_letters(column)})"
        reason = (f"a cell longer than {csv.field_size_limit()} characters"
                  if "field larger" in str(exc) else str(exc))
        raise TableError([f"{where}: {reason}; the file is not a table of numbers"]) from None
    return rows


def _long_field_column(line: str) -> int | None:
    """The 1-based column of the first cell of ``line`` past csv's field limit, if any."""
    limit = csv.field_size_limit()
    column, length, quoted = 1, 0, False
    for char in line:
        if char == '"':
            quoted = not quoted
        elif char == "," and not quoted:
            column, length = column + 1, 0
            continue
        length += 1
        if length > limit:
            return column
    return None


def _check_xlsx_xml(path: Path) -> None:
    """Refuse a workbook whose XML declares a DTD (entities, external references, entity
    bombs) or decompresses to more than :data:`MAX_TABLE_BYTES`, before openpyxl parses it."""
    try:
        with open_regular(path) as stream, zipfile.ZipFile(stream) as archive:
            members = archive.infolist()
            total = sum(info.file_size for info in members)
            if total > MAX_TABLE_BYTES:
                raise TableError([f"{path}: the workbook's parts decompress to "
                                  f"{format_bytes(total)}, more than "
                                  f"{format_bytes(MAX_TABLE_BYTES)}; split the trials"])
            for info in members:  # every part, whatever its name: a sheet's may be any
                _scan_xml(path, archive, info)
    except FileNotFoundError:
        raise TableError([f"{path}: no such file"]) from None
    except (BoundedReadError, OSError, zipfile.BadZipFile, zlib.error, EOFError) as exc:
        raise TableError([f"{path}: not a readable .xlsx workbook ({exc})"]) from None


def _scan_xml(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
    keep = b""
    with archive.open(info) as member:
        first = True
        while chunk := member.read(1 << 20):
            if first:
                if chunk[:2] in (b"\xff\xfe", b"\xfe\xff") or (
                        chunk[:1] == b"<" and b"\x00" in chunk[:4]):
                    raise TableError([f"{path}, part {info.filename}: XML that is not UTF-8; "
                                      "save the workbook again from a spreadsheet program"])
                if not chunk.removeprefix(b"\xef\xbb\xbf").lstrip().startswith(b"<"):
                    return  # not XML (an image, a binary part): openpyxl does not parse it
            first = False
            window = (keep + chunk).upper()
            if b"<!DOCTYPE" in window or b"<!ENTITY" in window:
                raise TableError([
                    f"{path}, part {info.filename}: the XML declares a DOCTYPE (entities "
                    "or external references); workbooks are read without them: save it "
                    "again from a spreadsheet program"])
            keep = chunk[-16:]


def _read_xlsx(path: Path) -> Iterator[tuple[str, str, _Cells]]:
    try:
        import openpyxl
    except ImportError as exc:
        raise TableError([f"{path}: reading .xlsx needs openpyxl: "
                          "pip install 'hapticframe[tables]'"]) from exc
    _check_xlsx_xml(path)
    try:
        book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # openpyxl raises many kinds for a damaged workbook
        raise TableError([f"{path}: not a readable .xlsx workbook ({type(exc).__name__}: "
                          f"{bound_text(str(exc))})"]) from None
    try:
        if not book.sheetnames:
            raise TableError([f"{path}: the workbook has no sheets"])
        for name in book.sheetnames:
            yield "sheet", name, _sheet_cells(path, name, book[name])
    finally:
        book.close()


def _sheet_cells(path: Path, name: str, sheet: Any) -> _Cells:
    """A sheet's rows, each as long as its last cell, its grid checked as it grows."""
    where = f"{path}, sheet {name!r}"
    rows_declared, columns_declared = sheet.max_row, sheet.max_column
    if rows_declared and columns_declared and rows_declared * columns_declared > MAX_CELLS:
        raise TableError([f"{where}: its dimension record ({sheet.calculate_dimension()}) "
                          f"declares {rows_declared} rows x {columns_declared} columns, more "
                          f"than the {MAX_CELLS} cells an import reads; delete the cells far "
                          "from the data"])
    # Without a dimension record, each row is as long as its last cell: a stray cell far
    # away is caught here, when the grid it spans grows past MAX_CELLS.
    sheet.reset_dimensions()
    rows: _Cells = []
    width = 0
    read = 0  # rows read, empty ones included (those after the last cell are dropped)
    try:
        for row in sheet.iter_rows(values_only=True):
            read += 1
            cells = len(row)
            while cells and row[cells - 1] is None:
                cells -= 1
            if not cells:
                continue
            width = max(width, cells)
            if read * width > MAX_CELLS:
                raise TableError([
                    f"{where}: the cell at row {read}, column {cells} "
                    f"({column_letters(cells)}) makes the sheet's grid {read} rows x {width} "
                    f"columns, more than the {MAX_CELLS} cells an import reads; delete the "
                    "cells far from the data"])
            rows.extend([] for _ in range(read - 1 - len(rows)))
            rows.append(list(row[:cells]))
    except TableError:
        raise
    except Exception as exc:  # openpyxl: a damaged sheet raises many kinds
        raise TableError([f"{where}, row {len(rows) + 1}: the sheet cannot be read "
                          f"({type(exc).__name__}: {bound_text(str(exc))})"]) from None
    return rows


def _read_hdf5(path: Path, dataset: str) -> Iterator[tuple[str, str, _Cells]]:
    try:
        handle = open_hdf5(path)
    except FileNotFoundError:
        raise TableError([f"{path}: no such file"]) from None
    except BoundedReadError as exc:
        raise TableError([f"{path}: {exc}"]) from None
    import h5py

    with handle:
        try:
            groups = [(n, g) for n, g in hdf5_members(handle) if isinstance(g, h5py.Group)]
        except BoundedReadError as exc:
            raise TableError([f"{path}: {exc}"]) from None
        if not groups:
            raise TableError([f"{path}: no groups (one group per trial)"])
        for name, group in groups:
            where = f"{path}, group {name!r}"
            try:
                node = hdf5_child(group, dataset)
                if not isinstance(node, h5py.Dataset) or node.ndim != 2:
                    raise TableError([f"{where}: no 2-D dataset {dataset!r} (set "
                                      "hdf5_dataset in the layout)"])
                values = read_hdf5_dataset(node, MAX_CELLS)
            except BoundedReadError as exc:
                raise TableError([f"{where}, dataset {dataset!r}: {exc}"]) from None
            yield "group", name, values.astype(np.float64).tolist()


def _blank(value: Any) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


class _Checker:
    """Reads the layout's lines of one table, collecting located problems."""

    def __init__(self, file: Path, kind: str, table: str, layout: TableLayout,
                 problems: list[str]) -> None:
        self.where = f"{file}, {kind} {table!r}"
        self.layout = layout
        self.problems = problems
        self.overflow = 0

    def cell_name(self, line: int, step: int) -> str:
        first = self.layout.first_step
        if self.layout.time_along == "columns":
            row, col = line, first + step
        else:
            row, col = first + step, line
        return f"{self.where}, row {row}, column {col} ({column_letters(col)})"

    def fail(self, text: str) -> None:
        if len(self.problems) < MAX_TABLE_ISSUES:
            self.problems.append(text)
        else:
            self.overflow += 1

    def line_values(self, cells: _Cells, line: int) -> list[Any]:
        """The cells of ``line`` from the first step on, trailing blanks cut."""
        if self.layout.time_along == "columns":
            values = list(cells[line - 1]) if line <= len(cells) else []
        else:
            values = [row[line - 1] if line <= len(row) else None for row in cells]
        values = values[self.layout.first_step - 1:]
        while values and _blank(values[-1]):
            values.pop()
        return values

    def numbers(self, cells: _Cells, line: int, steps: int, what: str) -> np.ndarray:
        values = self.line_values(cells, line)
        out = np.full(steps, np.nan)
        if len(values) > steps:
            self.fail(f"{self.cell_name(line, steps)}: {what} has a value past the trial's "
                      f"last step (the trial has {steps} steps)")
        for step in range(steps):
            value = values[step] if step < len(values) else None
            number = _number(value)
            if number is None:
                shown = "an empty cell" if _blank(value) else f"{str(value)[:40]!r}"
                self.fail(f"{self.cell_name(line, step)}: {what}: {shown} is not a number")
            elif not math.isfinite(number):
                self.fail(f"{self.cell_name(line, step)}: {what}: {number} is not finite")
            else:
                out[step] = number
        return out


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, str):
        text = value.strip(" \t\r\n")
        if not _DECIMAL.fullmatch(text):
            return None
        return float(text)
    return None


def _trial(cells: _Cells, checker: _Checker, name: str) -> TableTrial | None:
    layout = checker.layout
    used = layout.used_lines()
    first_line = next(iter(layout.channels.values())).lines[0]
    steps = len(checker.line_values(cells, first_line))
    if steps == 0:
        axis = "row" if layout.time_along == "columns" else "column"
        checker.fail(f"{checker.where}: {axis} {first_line} ({used[first_line]}) holds no "
                     f"steps from {'column' if axis == 'row' else 'row'} {layout.first_step} "
                     "on: the table is empty or does not match the layout")
        return None
    before = len(checker.problems) + checker.overflow
    channels = {}
    for cname, channel in layout.channels.items():
        lines = [checker.numbers(cells, line, steps, used[line]) for line in channel.lines]
        channels[cname] = np.stack(lines, axis=1).reshape((steps, *channel.sample_shape()))
    labels = {}
    for lname, label in layout.labels.items():
        values = checker.numbers(cells, label.line, steps, lname)
        if label.classes is not None:
            k = len(label.classes)
            bad = np.flatnonzero(np.isfinite(values)
                                 & ((values != np.round(values)) | (values < 0) | (values >= k)))
            for step in bad[:3]:
                checker.fail(f"{checker.cell_name(label.line, int(step))}: {lname}: "
                             f"{values[step]:g} is not a class index 0..{k - 1}")
        labels[lname] = values
    position = None
    if layout.position is not None:
        scale = 1.0 if layout.position.unit == "m" else 1e-3
        position = np.stack([checker.numbers(cells, line, steps, used[line])
                             for line in layout.position.lines], axis=1) * scale
    if len(checker.problems) + checker.overflow > before:
        return None
    return TableTrial(name, channels, labels, position)


def read_trials(path: str | Path, layout: TableLayout) -> list[TableTrial]:
    """Every trial in ``path`` read by ``layout``, all of them checked first.

    Raises
    ------
    TableError
        A file that cannot be read, a table that does not match the layout (each problem
        located by file, table, row and column), or more than :data:`MAX_CELLS` cells.
    """
    path = Path(path)
    problems: list[str] = []
    overflow = 0
    trials = []
    cells_read = 0
    for kind, name, cells in _tables(path, layout):
        cells_read += sum(len(row) for row in cells)
        if cells_read > MAX_CELLS:
            raise TableError([f"{path}: more than {MAX_CELLS} cells; split the tables"])
        checker = _Checker(path, kind, name, layout, problems)
        trial = _trial(cells, checker, Path(name).stem if kind == "file" else name)
        overflow += checker.overflow
        if trial is not None:
            trials.append(trial)
    if problems:
        raise TableError(problems, overflow)
    if len({t.name for t in trials}) != len(trials):
        raise TableError([f"{path}: two tables have the same name"])
    return trials
