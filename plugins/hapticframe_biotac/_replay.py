"""Recordings: the project's own ``.npz`` format (read and write) and BioTac CSV files (read).

Own format (``format = "hapticframe-biotac-recording"``, version 1): an ``.npz`` archive with

- ``timestamps_s`` (n,), ``frame_index`` (n,) int64,
- ``pac`` (n, P), ``pdc``, ``tac``, ``tdc`` (n,), ``electrodes`` (n, E), counts as float64,
- ``valid_<channel>`` per-word validity shaped like the channel, for channels that have any,
- optionally ``position_m`` (n, 2) and ``contact`` (n,) ground truth,
- ``metadata``: a JSON object stored as a 0-d unicode array (variant, format, version, and
  whatever the writer adds).

It is read with ``allow_pickle=False``: no code runs when a recording is opened.

CSV: a header row naming ``pdc, tac, tdc, pac1..pacP, ele1..eleE`` (P = 22, E = 19 on the
BioTac; 27 and 24 on the SP), in any order and any letter case; optional ``timestamp``
(seconds; frames are spaced one frame period apart from 0 without it); optional ground truth
``contact``, ``x_m``, ``y_m`` (all three or none). Other columns are ignored, and an empty
last header cell (rows ending in a comma, as in public BioTac logs) is allowed. Values may be
offset-removed counts, so they need only be finite numbers. Every fault is reported as a
:class:`ReplayFormatError` naming the file, line and column.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import save_npz as save_npz_atomically

from ._frame import SIGNAL_CHANNELS, BioTacFrames, layout_for

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
    if frames.position_m is not None and frames.contact is not None:
        arrays["position_m"] = frames.position_m
        arrays["contact"] = frames.contact
    path.parent.mkdir(parents=True, exist_ok=True)
    save_npz_atomically(path, **arrays)
    return path


def load_npz(path: str | Path) -> Recording:
    """Read an own-format recording (never unpickles)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {key: archive[key] for key in archive.files}
    except FileNotFoundError:
        raise ReplayFormatError(path, "no such file") from None
    except (OSError, ValueError, EOFError) as exc:  # not a zip, or an object array inside
        raise ReplayFormatError(path, f"not a readable .npz recording ({exc})") from None
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
    for name in SIGNAL_CHANNELS:
        if not np.isfinite(getattr(frames, name)).all():
            raise ReplayFormatError(path, f"channel {name!r} contains NaN or infinity")
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


def load_csv(path: str | Path, variant: str | None = None) -> Recording:
    """Read a BioTac CSV (see the module notes); ``variant`` None infers it from the header."""
    path = Path(path)
    try:
        handle = path.open(newline="", encoding="utf-8-sig")
    except FileNotFoundError:
        raise ReplayFormatError(path, "no such file") from None
    except OSError as exc:
        raise ReplayFormatError(path, f"cannot be opened ({exc.strerror})") from None
    with handle:
        reader = csv.reader(handle)
        try:
            rows = [(reader.line_num, row) for row in reader]
        except (csv.Error, UnicodeDecodeError) as exc:
            raise ReplayFormatError(path, f"not readable as CSV ({exc})", reader.line_num) from None
    rows = [(line, row) for line, row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise ReplayFormatError(path, "the file is empty; a header row is needed")
    header_line, header_row = rows[0]
    columns = _header(path, header_row, header_line)
    variant = variant or _infer_variant(set(columns))
    layout = layout_for(variant)
    required = _required_columns(variant)
    missing = [name for name in required if name not in columns]
    if missing:
        shown = ", ".join(missing[:6]) + (" ..." if len(missing) > 6 else "")
        raise ReplayFormatError(
            path, f"header lacks column(s) {shown} needed for a {variant} recording", header_line
        )
    truth_names = [name for name in ("contact", "x_m", "y_m") if name in columns]
    if truth_names and len(truth_names) != 3:
        raise ReplayFormatError(
            path, "ground truth needs the columns contact, x_m and y_m together", header_line
        )
    time_name = next((name for name in _TIME_COLUMNS if name in columns), None)
    wanted = required + truth_names + ([time_name] if time_name else [])
    data_rows = rows[1:]
    if not data_rows:
        raise ReplayFormatError(path, "no data rows after the header", header_line)
    table = np.empty((len(data_rows), len(wanted)))
    width = len(columns)
    for r, (line, row) in enumerate(data_rows):
        extra = [j for j in range(width, len(row)) if row[j].strip()]
        if extra:
            raise ReplayFormatError(
                path,
                f"row has {len(row)} cells but the header names {width}",
                line,
                extra[0] + 1,
            )
        for c, name in enumerate(wanted):
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
    col = {name: table[:, c] for c, name in enumerate(wanted)}
    if time_name:
        times = col[time_name]
        bad = np.flatnonzero(np.diff(times) <= 0)
        if bad.size:
            r = int(bad[0]) + 1
            raise ReplayFormatError(
                path, f"timestamp {times[r]:g} does not increase on {times[r - 1]:g}",
                data_rows[r][0], columns[time_name] + 1,
            )
    else:
        times = np.arange(len(data_rows), dtype=np.float64) * layout.frame_period_s
    frames = BioTacFrames(
        layout,
        times,
        np.column_stack([col[f"pac{i}"] for i in range(1, layout.n_pac + 1)]),
        col["pdc"],
        col["tac"],
        col["tdc"],
        np.column_stack([col[f"ele{i}"] for i in range(1, layout.n_electrodes + 1)]),
        position_m=np.column_stack([col["x_m"], col["y_m"]]) if truth_names else None,
        contact=col["contact"] if truth_names else None,
    )
    ignored = sorted(set(columns) - set(wanted))
    meta = {"format": "csv", "variant": variant, "n_frames": len(frames),
            "has_timestamps": time_name is not None, "ignored_columns": ignored}
    return Recording(frames, meta)


def load_recording(path: str | Path, variant: str | None = None) -> Recording:
    """Read a ``.npz`` or ``.csv`` recording, checking the variant when one is given."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        recording = load_npz(path)
        if variant and recording.frames.layout.variant != variant:
            raise ReplayFormatError(
                path,
                f"recording is a {recording.frames.layout.variant}, config says {variant}",
            )
        return recording
    if suffix == ".csv":
        return load_csv(path, variant)
    raise ReplayFormatError(path, "recordings are .npz or .csv files")

