"""Recordings: the project's own ``.npz`` format (read and write) and BioTac CSV files (read).

Own format (``format = "hapticframe-biotac-recording"``, version 1): an ``.npz`` archive with

- ``timestamps_s`` (n,), ``frame_index`` (n,) int64,
- ``pac`` (n, P), ``pdc``, ``tac``, ``tdc`` (n,), ``electrodes`` (n, E), counts as float64,
- ``valid_<channel>`` per-word validity shaped like the channel, for channels that have any,
- optionally ``position_m`` (n, 2) and ``contact`` (n,) ground truth (positions may come
  without contact labels, as from a real recording with the robot's positions; labels
  need positions),
- ``metadata``: a JSON object stored as a 0-d unicode array (variant, format, version, and
  whatever the writer adds).

It is read with ``allow_pickle=False``: no code runs when a recording is opened.

CSV: a header row naming ``pdc, tac, tdc, pac1..pacP, ele1..eleE`` (P = 22, E = 19 on the
BioTac; 27 and 24 on the SP), in any order and any letter case; optional ``timestamp``
(seconds; frames are spaced one frame period apart from 0 without it); optional ground truth
``x_m``, ``y_m`` (both or neither) and ``contact`` (only with them). Other columns are
ignored, and an empty last header cell (rows ending in a comma, as in public BioTac logs)
is allowed. Values may be offset-removed counts, so they need only be finite numbers;
``contact`` is 0 or 1. Every fault is reported as a :class:`ReplayFormatError` naming the
file, line and column.

Bounds: only regular files are read (a FIFO or a device is refused without blocking); a CSV
is streamed in blocks of lines, so memory beyond the returned frames stays within a block;
an ``.npz``'s declared shapes are checked against a byte limit from the members' headers
before anything is decompressed.
"""

from __future__ import annotations

import csv
import functools
import io
import itertools
import json
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import save_npz as save_npz_atomically
from hapticframe.bounded_io import (
    MAX_RECORDING_BYTES,
    BoundedReadError,
    format_bytes,
    open_regular,
    read_npz,
)

from ._frame import SIGNAL_CHANNELS, BioTacFrames, FrameLayout, layout_for

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "Recording",
    "ReplayFormatError",
    "load_csv",
    "load_npz",
    "load_recording",
    "save_npz",
]

FORMAT_NAME = "hapticframe-biotac-recording"
FORMAT_VERSION = 1
_TIME_COLUMNS = ("timestamp", "timestamp_s")


class ReplayFormatError(ValueError):
    """A recording that cannot be read, located as ``file:line:column: message``."""

    def __init__(
        self, path: str | Path, message: str, line: int | None = None, column: int | None = None
    ) -> None:
        self.path = str(path)
        self.line = line
        self.column = column
        where = self.path + "".join(f":{x}" for x in (line, column) if x is not None)
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class Recording:
    """Frames read from a file and the file's metadata."""

    frames: BioTacFrames
    metadata: dict[str, Any] = field(default_factory=dict)


# --- own format -------------------------------------------------------------------------------


def save_npz(
    path: str | Path, frames: BioTacFrames, metadata: dict[str, Any] | None = None
) -> Path:
    """Write ``frames`` in the own format; ``metadata`` must be JSON-serialisable."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ValueError(f"recordings are .npz files, got {path.name!r}")
    meta = {**(metadata or {}), "format": FORMAT_NAME, "version": FORMAT_VERSION,
            "variant": frames.layout.variant, "n_frames": len(frames)}
    arrays: dict[str, NDArray[Any]] = {
        "metadata": np.array(json.dumps(meta, allow_nan=False)),
        "timestamps_s": frames.timestamps_s,
    }
    if frames.frame_index is not None:  # always, once the frames are built
        arrays["frame_index"] = frames.frame_index
    for name in SIGNAL_CHANNELS:
        arrays[name] = getattr(frames, name)
        if name in frames.word_valid:
            arrays[f"valid_{name}"] = frames.word_valid[name]
    if frames.position_m is not None:
        arrays["position_m"] = frames.position_m
    if frames.contact is not None:
        arrays["contact"] = frames.contact
    path.parent.mkdir(parents=True, exist_ok=True)
    save_npz_atomically(path, **arrays)
    return path


def _located_read_error(path: Path, exc: BoundedReadError) -> ReplayFormatError:
    return ReplayFormatError(path, str(exc))


def _open(path: Path) -> IO[bytes]:
    """``path`` opened when it is a regular file, else a located error."""
    try:
        return open_regular(path)
    except FileNotFoundError:
        raise ReplayFormatError(path, "no such file") from None
    except BoundedReadError as exc:
        raise _located_read_error(path, exc) from None


def _real(path: Path, arrays: dict[str, NDArray[Any]], name: str, kinds: str = "biuf") -> None:
    """Refuse an array whose dtype is not a real number (complex, strings, ...)."""
    if name in arrays and arrays[name].dtype.kind not in kinds:
        what = "complex" if arrays[name].dtype.kind == "c" else "not numeric"
        raise ReplayFormatError(
            path, f"array {name!r} is {what} ({arrays[name].dtype}); a recording holds real "
            "numbers"
        )


def _first_bad(mask: NDArray[np.bool_]) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def _check_truth(path: Path, frames: BioTacFrames) -> None:
    """Ground truth must be finite positions and 0/1 contact labels (row named)."""
    if frames.position_m is not None:
        bad = ~np.isfinite(frames.position_m)
        if bad.any():
            row, axis = _first_bad(bad)
            raise ReplayFormatError(
                path, f"'position_m' row {row} ({'xy'[axis]}) is "
                f"{frames.position_m[row, axis]:g}; ground-truth positions must be finite"
            )
    if frames.contact is not None:
        bad = (frames.contact != 0) & (frames.contact != 1)
        if bad.any():
            (row,) = _first_bad(bad)
            raise ReplayFormatError(
                path, f"'contact' row {row} is {frames.contact[row]:g}; contact labels are 0 "
                "(free) or 1 (contact)"
            )


def load_npz(path: str | Path, *, max_bytes: int = MAX_RECORDING_BYTES) -> Recording:
    """Read an own-format recording (never unpickles).

    Only a regular file is read, and its arrays' declared shapes are checked against
    ``max_bytes`` before anything is decompressed.
    """
    path = Path(path)
    with _open(path) as handle:
        try:
            arrays = read_npz(handle, max_bytes=max_bytes)
        except BoundedReadError as exc:
            raise _located_read_error(path, exc) from None
    if "metadata" not in arrays:
        raise ReplayFormatError(path, "no 'metadata' entry: not a hapticframe BioTac recording")
    try:
        meta = json.loads(str(arrays.pop("metadata")))
    except json.JSONDecodeError as exc:
        raise ReplayFormatError(path, f"metadata is not JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_NAME:
        raise ReplayFormatError(path, f"metadata does not name the format {FORMAT_NAME!r}")
    if meta.get("version") != FORMAT_VERSION:
        raise ReplayFormatError(
            path,
            f"format version {meta.get('version')!r} is not supported (expected {FORMAT_VERSION})",
        )
    missing = [k for k in ("timestamps_s", *SIGNAL_CHANNELS) if k not in arrays]
    if missing:
        raise ReplayFormatError(path, f"missing arrays {missing}")
    for name in ("timestamps_s", *SIGNAL_CHANNELS, "position_m", "contact"):
        _real(path, arrays, name)
    _real(path, arrays, "frame_index", "iu")
    for name in SIGNAL_CHANNELS:
        _real(path, arrays, f"valid_{name}", "b")
    for name in ("timestamps_s", *SIGNAL_CHANNELS):
        values = arrays[name]
        bad = ~np.isfinite(values)
        if bad.any():
            where = _first_bad(bad)
            at = f" row {where[0]}" if where else ""
            at += f" column {where[1]}" if len(where) > 1 else ""
            raise ReplayFormatError(
                path, f"{name!r}{at} is {values[where]:g}; "
                f"{'times' if name == 'timestamps_s' else 'counts'} must be finite (mark a "
                "lost word in valid_<channel> instead)"
            )
    try:
        layout = layout_for(str(meta.get("variant")))
        frames = BioTacFrames.from_channels(
            layout,
            arrays["timestamps_s"],
            {name: arrays[name] for name in SIGNAL_CHANNELS},
            word_valid={
                name: arrays[f"valid_{name}"]
                for name in SIGNAL_CHANNELS
                if f"valid_{name}" in arrays
            },
            frame_index=arrays.get("frame_index"),
            position_m=arrays.get("position_m"),
            contact=arrays.get("contact"),
        )
    except ValueError as exc:
        raise ReplayFormatError(path, str(exc)) from None
    _check_truth(path, frames)
    return Recording(frames, meta)


# --- CSV ---------------------------------------------------------------------------------------


def _required_columns(variant: str) -> list[str]:
    layout = layout_for(variant)
    return (["pdc", "tac", "tdc"] + [f"pac{i}" for i in range(1, layout.n_pac + 1)]
            + [f"ele{i}" for i in range(1, layout.n_electrodes + 1)])


def _infer_variant(names: set[str]) -> str:
    return "biotac_sp" if {"ele20", "ele24"} <= names else "biotac"


def _header(path: Path, row: list[str], line: int) -> dict[str, int]:
    cells = [c.strip().lower() for c in row]
    while cells and cells[-1] == "":
        cells.pop()  # rows ending in a comma
    columns: dict[str, int] = {}
    for j, name in enumerate(cells):
        if not name:
            raise ReplayFormatError(path, "empty column name in the header", line, j + 1)
        if name in columns:
            raise ReplayFormatError(
                path, f"column {name!r} appears twice in the header", line, j + 1
            )
        columns[name] = j
    return columns


#: Lines parsed at a time: a block's text and its float64 table take a few MB, whatever the
#: size of the file.
_BLOCK_LINES = 8192


class _CsvLayout:
    """What the header says: the columns to read, in ``wanted`` order, and the row width."""

    def __init__(self, path: Path, columns: dict[str, int], wanted: list[str]) -> None:
        self.path = path
        self.columns = columns
        self.wanted = wanted
        self.indices = [columns[name] for name in wanted]
        self.width = len(columns)


def _csv_row(path: Path, line: str, number: int) -> list[str]:
    try:
        return next(csv.reader([line]), [])
    except csv.Error as exc:
        raise ReplayFormatError(path, f"not readable as CSV ({exc})", number) from None


def _fast_block(block: list[str], layout: _CsvLayout) -> NDArray[np.float64] | None:
    """The block's table by numpy's C parser, or None when any line needs a closer look
    (quotes, extra cells, an empty or unparsable cell, a value that is not finite)."""
    if '"' in "".join(block):
        return None
    for line in block:
        commas = line.count(",")
        # Cells past the header's width are allowed only as one empty trailing cell.
        if commas >= layout.width and (
            commas > layout.width or not line.rstrip("\r\n").endswith(",")
        ):
            return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an all-blank block: "input contained no data"
            table = np.loadtxt(
                block, dtype=np.float64, delimiter=",", comments=None, usecols=layout.indices,
                ndmin=2, encoding=None,
            )
    except ValueError:
        return None
    if table.shape[1] != len(layout.indices) or not np.isfinite(table).all():
        return None
    return table


def _slow_block(
    block: list[str], first_line: int, layout: _CsvLayout
) -> tuple[NDArray[np.float64], list[int]]:
    """The block's table and the line of each row, cell by cell: every fault located."""
    path, columns, width = layout.path, layout.columns, layout.width
    reader = csv.reader(block)
    rows: list[tuple[int, list[str]]] = []
    try:
        for row in reader:
            if any(cell.strip() for cell in row):
                rows.append((first_line + reader.line_num - 1, row))
    except csv.Error as exc:
        raise ReplayFormatError(
            path, f"not readable as CSV ({exc})", first_line + reader.line_num - 1
        ) from None
    table = np.empty((len(rows), len(layout.wanted)))
    for r, (line, row) in enumerate(rows):
        extra = [j for j in range(width, len(row)) if row[j].strip()]
        if extra:
            raise ReplayFormatError(
                path, f"row has {len(row)} cells but the header names {width}", line,
                extra[0] + 1,
            )
        for c, name in enumerate(layout.wanted):
            j = columns[name]
            if j >= len(row) or not row[j].strip():
                raise ReplayFormatError(path, f"column {name!r} is empty", line, j + 1)
            text = row[j].strip()
            try:
                value = float(text)
            except ValueError:
                raise ReplayFormatError(
                    path, f"column {name!r}: {text!r} is not a number", line, j + 1
                ) from None
            if not np.isfinite(value):
                raise ReplayFormatError(
                    path, f"column {name!r}: {text!r} is not finite", line, j + 1
                )
            table[r, c] = value
    return table, [line for line, _ in rows]


def _block_lines(block: list[str], first_line: int, layout: _CsvLayout) -> list[int]:
    """The line of each row of a block (parsed again, only to locate a fault)."""
    return _slow_block(block, first_line, layout)[1]


def _check_block(
    table: NDArray[np.float64],
    lines: Callable[[], list[int]],
    layout: _CsvLayout,
    previous_time: float | None,
) -> None:
    """Timestamps increase (also across blocks) and contact labels are 0 or 1; ``lines``
    gives each row's line, computed only to locate a fault."""
    path, wanted = layout.path, layout.wanted
    time_name = wanted[-1] if wanted[-1] in _TIME_COLUMNS else None
    if time_name is not None and len(table):
        times = table[:, -1]
        if previous_time is not None:
            times = np.concatenate([[previous_time], times])
        bad = np.flatnonzero(np.diff(times) <= 0)
        if bad.size:
            r = int(bad[0]) + 1
            row = r - (previous_time is not None)
            raise ReplayFormatError(
                path, f"timestamp {times[r]:g} does not increase on {times[r - 1]:g}",
                lines()[row], layout.columns[time_name] + 1,
            )
    if "contact" in wanted:
        contact = table[:, wanted.index("contact")]
        bad = np.flatnonzero((contact != 0) & (contact != 1))
        if bad.size:
            r = int(bad[0])
            raise ReplayFormatError(
                path, f"column 'contact': {contact[r]:g} is not a contact label (0 free, "
                "1 contact)", lines()[r], layout.columns["contact"] + 1,
            )


def load_csv(
    path: str | Path, variant: str | None = None, *, max_bytes: int = MAX_RECORDING_BYTES
) -> Recording:
    """Read a BioTac CSV (see the module notes); ``variant`` None infers it from the header.

    The file is streamed in blocks of lines: besides the frames it returns (float64, about
    8 bytes a cell read), memory stays within a block. A file whose frames would take more
    than ``max_bytes`` is refused, from an estimate after the first block.
    """
    path = Path(path)
    with _open(path) as raw:
        size = os.fstat(raw.fileno()).st_size
        text = io.TextIOWrapper(raw, encoding="utf-8-sig", newline="")
        lines_read = [0]
        try:
            return _read_csv(path, text, size, variant, max_bytes, lines_read)
        except UnicodeDecodeError as exc:
            raise ReplayFormatError(
                path, f"not readable as CSV ({exc})", lines_read[0] + 1
            ) from None


def _read_csv(
    path: Path,
    text: IO[str],
    size: int,
    variant: str | None,
    max_bytes: int,
    lines_read: list[int],
) -> Recording:
    header_row: list[str] | None = None
    header_line = 0
    for line in text:
        lines_read[0] += 1
        row = _csv_row(path, line, lines_read[0])
        if any(cell.strip() for cell in row):
            header_row, header_line = row, lines_read[0]
            break
    if header_row is None:
        raise ReplayFormatError(path, "the file is empty; a header row is needed")
    columns = _header(path, header_row, header_line)
    variant = variant or _infer_variant(set(columns))
    frame_layout = layout_for(variant)
    required = _required_columns(variant)
    missing = [name for name in required if name not in columns]
    if missing:
        shown = ", ".join(missing[:6]) + (" ..." if len(missing) > 6 else "")
        raise ReplayFormatError(
            path, f"header lacks column(s) {shown} needed for a {variant} recording", header_line
        )
    truth_names = [name for name in ("x_m", "y_m", "contact") if name in columns]
    if truth_names and truth_names[:2] != ["x_m", "y_m"]:
        raise ReplayFormatError(
            path, "ground truth needs the columns x_m and y_m together (contact only with "
            "them)", header_line
        )
    time_name = next((name for name in _TIME_COLUMNS if name in columns), None)
    layout = _CsvLayout(path, columns, required + truth_names + ([time_name] if time_name else []))
    # Each frame keeps 8 bytes per column read, its timestamp and its frame index.
    row_bytes = 8 * (len(layout.wanted) + 2)
    chunks: list[NDArray[np.float64] | None] = []
    n = 0
    chars = 0
    previous_time: float | None = None
    while block := list(itertools.islice(text, _BLOCK_LINES)):
        first_line = lines_read[0] + 1
        lines_read[0] += len(block)
        table = _fast_block(block, layout)
        if table is None:
            table, rows_at = _slow_block(block, first_line, layout)
            _check_block(table, functools.partial(list, rows_at), layout, previous_time)
        else:
            _check_block(
                table, functools.partial(_block_lines, block, first_line, layout), layout,
                previous_time,
            )
        if not len(table):
            continue
        n += len(table)
        chars += sum(map(len, block))
        # After the first block the whole file's rows are estimated from its size, to refuse
        # a file far too large at once; past that, the rows read so far are counted exactly.
        estimate = max(n, round(n * size / max(chars, 1))) if not chunks else n
        if estimate * row_bytes > 1.25 * max_bytes or n * row_bytes > max_bytes:
            expected = max(estimate, n)
            raise ReplayFormatError(
                path, f"{'about ' if expected > n else ''}{expected:,} rows of "
                f"{len(layout.wanted)} columns ({format_bytes(size)} on disk) take "
                f"{format_bytes(expected * row_bytes)} in memory; the limit for one recording "
                f"is {format_bytes(max_bytes)}: split the recording into several files"
            )
        if time_name:
            previous_time = float(table[-1, -1])
        chunks.append(table)
    if not n:
        raise ReplayFormatError(path, "no data rows after the header", header_line)
    return _assemble(chunks, n, layout, frame_layout, variant, time_name, truth_names)


def _assemble(
    chunks: list[NDArray[np.float64] | None],
    n: int,
    layout: _CsvLayout,
    frame_layout: FrameLayout,
    variant: str,
    time_name: str | None,
    truth_names: Sequence[str],
) -> Recording:
    """The frames from the blocks' tables, each block freed once copied (no second copy of
    the whole recording at any time)."""
    n_pac, n_ele = frame_layout.n_pac, frame_layout.n_electrodes
    pdc, tac, tdc = np.empty(n), np.empty(n), np.empty(n)
    pac, electrodes = np.empty((n, n_pac)), np.empty((n, n_ele))
    contact = np.empty(n) if "contact" in truth_names else None
    position = np.empty((n, 2)) if truth_names else None
    times = (np.empty(n) if time_name
             else np.arange(n, dtype=np.float64) * frame_layout.frame_period_s)
    start = 0
    for i, table in enumerate(chunks):
        assert table is not None
        rows = slice(start, start + len(table))
        # Column order of a table: pdc, tac, tdc, pac1.., ele1.., [x_m, y_m, [contact]],
        # [time].
        pdc[rows], tac[rows], tdc[rows] = table[:, 0], table[:, 1], table[:, 2]
        pac[rows] = table[:, 3 : 3 + n_pac]
        electrodes[rows] = table[:, 3 + n_pac : 3 + n_pac + n_ele]
        if position is not None:
            position[rows] = table[:, 3 + n_pac + n_ele : 5 + n_pac + n_ele]
        if contact is not None:
            contact[rows] = table[:, 5 + n_pac + n_ele]
        if time_name:
            times[rows] = table[:, -1]
        start += len(table)
        chunks[i] = None
    frames = BioTacFrames(
        frame_layout, times, pac, pdc, tac, tdc, electrodes,
        position_m=position, contact=contact,
    )
    ignored = sorted(set(layout.columns) - set(layout.wanted))
    meta = {"format": "csv", "variant": variant, "n_frames": len(frames),
            "has_timestamps": time_name is not None, "ignored_columns": ignored}
    return Recording(frames, meta)


def load_recording(
    path: str | Path, variant: str | None = None, *, max_bytes: int = MAX_RECORDING_BYTES
) -> Recording:
    """Read a ``.npz`` or ``.csv`` recording, checking the variant when one is given.

    Only regular files are read, and a recording whose arrays would take more than
    ``max_bytes`` in memory is refused before it is loaded.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        recording = load_npz(path, max_bytes=max_bytes)
        if variant and recording.frames.layout.variant != variant:
            raise ReplayFormatError(
                path,
                f"recording is a {recording.frames.layout.variant}, config says {variant}",
            )
        return recording
    if suffix == ".csv":
        return load_csv(path, variant, max_bytes=max_bytes)
    raise ReplayFormatError(path, "recordings are .npz or .csv files")

