"""Bounded, located reading of a saved model's files: JSON metadata and ``.npz`` arrays.

Every failure is a :class:`ValueError` that names the file and says what is wrong with it,
so a corrupt artifact is refused as bad input before anything is built from it (a build
turns it into exit 2, located at the component). Reads are bounded: a file must be a
regular file (not a FIFO or a device) no larger than what the model can need, and an
``.npz`` member's declared shape and dtype are checked from its header before its data is
decompressed.

Persistent plugins read their saved models through it (``load``); a lab's plugin can too.
"""

from __future__ import annotations

import json
import math
import re
import stat
import zipfile
import zlib
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

__all__ = [
    "MAX_METADATA_BYTES",
    "check_regular_file",
    "npz_budget",
    "read_json_object",
    "read_npz_arrays",
    "schema_error",
]

#: Largest metadata file read (bytes); ours are a few kB.
MAX_METADATA_BYTES = 4 * 2**20
# Per-member allowance for the zip and .npy headers beside the data.
_NPZ_MEMBER_OVERHEAD = 4096
_SCHEMA_ERRORS_SHOWN = 5


class _Refused(ValueError):
    """A JSON construct that is valid for Python's parser but not in an artifact."""


def check_regular_file(path: Path, max_bytes: int) -> int:
    """Size of ``path`` in bytes; ValueError unless it is a non-empty regular file of at
    most ``max_bytes``."""
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ValueError(f"{path} is missing") from None
    except OSError as exc:
        raise ValueError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{path} is not a regular file")
    if info.st_size == 0:
        raise ValueError(f"{path} is empty (an interrupted save?); train the model again")
    if info.st_size > max_bytes:
        raise ValueError(
            f"{path} holds {info.st_size} bytes, more than the {max_bytes} that this model "
            "can need; it is not the artifact that was saved"
        )
    return int(info.st_size)


def _refuse_constant(name: str) -> Any:
    raise _Refused(f"holds {name}, which is not a number JSON allows")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _Refused(f"repeats the key {key[:80]!r}")
        out[key] = value
    return out


def read_json_object(path: Path, max_bytes: int = MAX_METADATA_BYTES) -> dict[str, Any]:
    """The JSON object in ``path``: strict JSON (no NaN or Infinity, no repeated keys).

    Raises
    ------
    ValueError
        Naming the file: missing, not a regular file, empty, too large, not UTF-8, not
        JSON (a truncated file), nested too deeply, or not an object at the top.
    """
    check_regular_file(path, max_bytes)
    try:
        with path.open("rb") as stream:
            raw = stream.read(max_bytes + 1)  # bounded even if the file grew since stat()
    except OSError as exc:
        raise ValueError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise ValueError(f"{path} is larger than {max_bytes} bytes")
    try:
        value = json.loads(
            raw.decode("utf-8"), parse_constant=_refuse_constant, object_pairs_hook=_unique_keys
        )
    except UnicodeDecodeError:
        raise ValueError(f"{path} is not UTF-8 text; it is not a model's metadata") from None
    except _Refused as exc:
        raise ValueError(f"{path} {exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"{path} is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}); "
            "the file may be truncated"
        ) from None
    except RecursionError:
        raise ValueError(f"{path} nests too deeply to be a model's metadata") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path} holds a JSON {type(value).__name__}, not an object")
    return value


def schema_error(path: Path, exc: ValidationError, prefix: str = "") -> ValueError:
    """A ValueError naming ``path`` and the first few fields ``exc`` found wrong (the
    fields' dotted locations, under ``prefix``, and what they must be; never the offending
    values, which may be huge)."""
    errors = exc.errors(include_input=False, include_url=False)
    shown = []
    for error in errors[:_SCHEMA_ERRORS_SHOWN]:
        parts = ([prefix] if prefix else []) + [str(part) for part in error["loc"]]
        where = ".".join(parts) or "the top level"
        # "a valid dictionary or instance of _Thresholds": the class name means nothing to a user.
        message = re.sub(r" or instance of \w+", "", error["msg"])
        shown.append(f"{where}: {message}")
    more = len(errors) - len(shown)
    tail = f" (and {more} more)" if more > 0 else ""
    return ValueError(f"{path} does not hold a valid model: {'; '.join(shown)}{tail}")


def npz_budget(shapes: Mapping[str, tuple[int, ...]]) -> int:
    """Largest ``.npz`` size (bytes) plausible for float64 arrays of ``shapes``."""
    return sum(8 * math.prod(s) + _NPZ_MEMBER_OVERHEAD for s in shapes.values()) + 65536


def _npz_headers(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype[Any]]]:
    """Each member's declared shape and dtype, read from its header alone."""
    headers: dict[str, tuple[tuple[int, ...], np.dtype[Any]]] = {}
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = info.filename.removesuffix(".npy")
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                if version == (1, 0):
                    shape, _, dtype = np.lib.format.read_array_header_1_0(member)
                elif version == (2, 0):
                    shape, _, dtype = np.lib.format.read_array_header_2_0(member)
                else:
                    raise ValueError(f"member {name!r} has .npy format {version}")
            headers[name] = (tuple(int(n) for n in shape), np.dtype(dtype))
    return headers


def read_npz_arrays(
    path: Path,
    shapes: Mapping[str, tuple[int, ...]],
    optional: Collection[str] = (),
    max_bytes: int | None = None,
) -> dict[str, NDArray[np.float64]]:
    """The arrays ``shapes`` names, as finite float64, from the ``.npz`` at ``path``.

    Each member's shape and dtype are checked against ``shapes`` from its header before
    any data is read; the file may be no larger than ``max_bytes`` (default:
    :func:`npz_budget` of ``shapes``).
    Names in ``optional`` may be absent (then absent from the result). Other members
    are ignored.

    Raises
    ------
    ValueError
        Naming the file: missing, empty, too large, not an ``.npz`` (or truncated),
        lacking a member, a member of another shape or of a non-floating dtype (object
        arrays included: nothing is unpickled), or holding NaN or infinity.
    """
    check_regular_file(path, npz_budget(shapes) if max_bytes is None else max_bytes)
    try:
        headers = _npz_headers(path)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as exc:
        raise ValueError(
            f"{path} is not a readable .npz archive (truncated or another kind of file): {exc}"
        ) from None
    missing = [k for k in shapes if k not in headers and k not in optional]
    if missing:
        raise ValueError(f"{path} lacks the array(s) {', '.join(missing)}")
    wanted = [k for k in shapes if k in headers]
    for key in wanted:
        shape, dtype = headers[key]
        if dtype.kind != "f":
            raise ValueError(f"{path}: {key} holds {dtype} values, not floating-point numbers")
        if shape != tuple(shapes[key]):
            raise ValueError(f"{path}: {key} has shape {shape}, expected {tuple(shapes[key])}")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: np.array(data[k], dtype=np.float64) for k in wanted}
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as exc:
        raise ValueError(f"{path} is truncated or corrupt: {exc}") from None
    for key, array in arrays.items():
        bad = int(np.count_nonzero(~np.isfinite(array)))
        if bad:
            raise ValueError(f"{path}: {key} holds {bad} NaN or infinite value(s)")
    return arrays
