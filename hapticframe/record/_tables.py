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
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hapticframe._config._load import load_file
from hapticframe._errors import ExperimentError, HapticframeError, Issue

__all__ = [
    "MAX_TABLE_ISSUES",
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

_NAME = r"^[a-z][a-z0-9_]*$"


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
    rate_hz: float = Field(gt=0, le=1e6, allow_inf_nan=False)
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
            if not re.match(_NAME, name):
                raise ValueError(f"{name!r} is not a channel name (lowercase letters, digits "
                                 "and '_', starting with a letter)")
        if len(set(names)) != len(names):
            raise ValueError("a label has the name of a channel")
        if self.position is not None and "position_m" in names:
            raise ValueError("'position_m' is the position's channel; rename the other one")
        return self

    def used_lines(self) -> dict[int, str]:
        """Every line the layout reads and what it is (for messages)."""
        used: dict[int, str] = {}
        for name, channel in self.channels.items():
            for i, line in enumerate(channel.lines):
                used[line] = f"{name}[{i}]" if len(channel.lines) > 1 else name
        for name, label in self.labels.items():
            used[label.line] = name
        if self.position is not None:
            for axis, line in zip("xyz", self.position.lines, strict=True):
                used[line] = f"position {axis}"
        return used


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
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".csv")
        if not files:
            raise TableError([f"{path}: a directory of trials must hold .csv files; it has "
                              "none"])
        for file in files:
            yield "file", file.name, _read_csv(file)
        return
    if not path.is_file():
        raise TableError([f"{path}: no such file or directory"])
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


def _read_csv(path: Path) -> _Cells:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise TableError([f"{path}: cannot be read as UTF-8 text ({exc})"]) from None
    return [list(row) for row in csv.reader(io.StringIO(text))]


def _read_xlsx(path: Path) -> Iterator[tuple[str, str, _Cells]]:
    try:
        import openpyxl
    except ImportError as exc:
        raise TableError([f"{path}: reading .xlsx needs openpyxl: "
                          "pip install 'hapticframe[tables]'"]) from exc
    try:
        book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # openpyxl raises many kinds for a damaged workbook
        raise TableError([f"{path}: not a readable .xlsx workbook ({type(exc).__name__}: "
                          f"{exc})"]) from None
    try:
        if not book.sheetnames:
            raise TableError([f"{path}: the workbook has no sheets"])
        for name in book.sheetnames:
            yield "sheet", name, [list(row) for row in book[name].iter_rows(values_only=True)]
    finally:
        book.close()


def _read_hdf5(path: Path, dataset: str) -> Iterator[tuple[str, str, _Cells]]:
    try:
        import h5py
    except ImportError as exc:
        raise TableError([f"{path}: reading HDF5 needs h5py: pip install 'hapticframe[tables]'"]
                         ) from exc
    try:
        handle = h5py.File(path, "r")
    except OSError as exc:
        raise TableError([f"{path}: not a readable HDF5 file ({exc})"]) from None
    with handle:
        groups = sorted(k for k in handle if isinstance(handle[k], h5py.Group))
        if not groups:
            raise TableError([f"{path}: no groups (one group per trial)"])
        for name in groups:
            node = handle[name].get(dataset)
            if not isinstance(node, h5py.Dataset) or node.ndim != 2:
                raise TableError([f"{path}, group {name!r}: no 2-D dataset {dataset!r} "
                                  "(set hdf5_dataset in the layout)"])
            if node.dtype.kind not in "biuf":
                raise TableError([f"{path}, group {name!r}, dataset {dataset!r}: "
                                  f"{node.dtype} is not numeric"])
            yield "group", name, np.asarray(node, dtype=np.float64).tolist()


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
        try:
            return float(value.strip())
        except ValueError:
            return None
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
