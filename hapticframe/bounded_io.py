"""Bounded reading of recording files: regular files only, ``.npz`` shapes checked first.

A recording path may name anything: a FIFO (opening it for reading would wait forever for a
writer), a device such as ``/dev/zero`` (endless), a ``.npy`` or a truncated archive, or a
small ``.npz`` whose compressed members declare gigabytes. :func:`open_regular` refuses
everything but a regular file without blocking, and :func:`read_npz` reads each member's
``.npy`` header (shape and dtype) before decompressing anything, refusing archives whose
declared arrays exceed a byte limit, with the estimate in the message.

Failures are :class:`BoundedReadError` with a message that does not name the file: callers
add the file in their own located error type.

The recording readers of ``trace-recording`` and ``biotac`` use it, and a lab's plugin can;
:mod:`hapticframe.artifacts` reads saved models the same way.
"""

from __future__ import annotations

import math
import os
import stat
import zipfile
import zlib
from collections.abc import Callable
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_RECORDING_BYTES", "BoundedReadError", "format_bytes", "open_regular", "read_npz"]

#: Most bytes of decoded arrays one recording may hold in memory (2 GiB: about six million
#: BioTac frames, 16 hours at 100 Hz).
MAX_RECORDING_BYTES = 2 * 1024**3

_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


class BoundedReadError(ValueError):
    """A file that is refused before (or while) reading it; the message says why."""


def format_bytes(n: float) -> str:
    """``n`` bytes for a message: ``3.5 GB``, ``120 MB``, ``12 kB``."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{int(n)} bytes"


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISDIR(mode):
        return "a directory"
    return "not a regular file"


def open_regular(path: str | os.PathLike[str]) -> IO[bytes]:
    """``path`` opened for binary reading, when it is (or links to) a regular file.

    Opened non-blocking so that a FIFO is refused at once rather than waited on.

    Raises
    ------
    FileNotFoundError
        When nothing is there.
    BoundedReadError
        When it is a FIFO, a device, a socket or a directory, or cannot be opened.
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise
    except IsADirectoryError:
        raise BoundedReadError("the path is a directory, not a file") from None
    except OSError as exc:
        raise BoundedReadError(f"the file cannot be opened ({exc.strerror})") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise BoundedReadError(
                f"the path is {_kind(mode)}, not a regular file; recordings are read from "
                "files only"
            )
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _declared(member: IO[bytes], name: str) -> tuple[tuple[int, ...], np.dtype[Any]]:
    """Shape and dtype an ``.npy`` member declares, read from its header alone."""
    try:
        version = np.lib.format.read_magic(member)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(member)
        elif version in ((2, 0), (3, 0)):
            shape, _, dtype = np.lib.format.read_array_header_2_0(member)
        else:
            raise ValueError(f"unsupported .npy format version {version}")
    except (ValueError, EOFError, OSError, zipfile.BadZipFile, zlib.error) as exc:
        raise BoundedReadError(f"array {name!r} has no readable .npy header ({exc})") from None
    return tuple(int(n) for n in shape), np.dtype(dtype)


def read_npz(
    file: IO[bytes],
    *,
    keep: Callable[[str], bool] | None = None,
    max_bytes: int = MAX_RECORDING_BYTES,
) -> dict[str, NDArray[Any]]:
    """The arrays of an ``.npz`` archive opened by :func:`open_regular` (never unpickles).

    Every member's declared shape and dtype are read from its header first; only when the
    arrays to load (those whose name ``keep`` accepts, default all) declare at most
    ``max_bytes`` in all are they decompressed, each reading exactly its declared size.

    Raises
    ------
    BoundedReadError
        When the file is a ``.npy``, not a zip archive, truncated or corrupt, holds an
        object array, or declares more than ``max_bytes`` (the message gives the estimate).
    """
    start = file.read(len(_NPY_MAGIC))
    file.seek(0)
    if start.startswith(_NPY_MAGIC):
        raise BoundedReadError(
            "the file is a single .npy array, not an .npz archive; save recordings with "
            "numpy.savez (or give the file its .npy name)"
        )
    if not start.startswith(_ZIP_MAGIC):
        raise BoundedReadError("the file is not an .npz archive (no zip signature)")
    try:
        archive = zipfile.ZipFile(file)
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        raise BoundedReadError(
            f"the file is truncated or not a valid .npz archive ({exc}); write it again"
        ) from None
    with archive:
        members = [
            info for info in archive.infolist()
            if info.filename.endswith(".npy")
            and (keep is None or keep(info.filename[: -len(".npy")]))
        ]
        declared: list[tuple[zipfile.ZipInfo, str, tuple[int, ...], np.dtype[Any]]] = []
        total = 0
        for info in members:
            name = info.filename[: -len(".npy")]
            with archive.open(info) as member:
                shape, dtype = _declared(member, name)
            if dtype.hasobject:
                raise BoundedReadError(
                    f"array {name!r} holds Python objects ({dtype}): loading it would "
                    "unpickle, which recordings never do (allow_pickle=False); save numbers "
                    "and strings only"
                )
            total += math.prod(shape) * dtype.itemsize
            declared.append((info, name, shape, dtype))
        if total > max_bytes:
            largest = sorted(declared, key=lambda d: -math.prod(d[2]) * d[3].itemsize)[:3]
            shown = ", ".join(
                f"{name!r} {' x '.join(map(str, shape)) or 'scalar'} {dtype}"
                for _, name, shape, dtype in largest
            )
            raise BoundedReadError(
                f"the file declares arrays of {format_bytes(total)} ({shown}); the limit for "
                f"one recording is {format_bytes(max_bytes)}: split the recording into "
                "several files"
            )
        arrays: dict[str, NDArray[Any]] = {}
        for info, name, _, _ in declared:
            try:
                with archive.open(info) as member:
                    arrays[name] = np.lib.format.read_array(member, allow_pickle=False)
            except (ValueError, EOFError, OSError, zipfile.BadZipFile, zlib.error) as exc:
                raise BoundedReadError(
                    f"array {name!r} is truncated or corrupt ({exc}); write the file again"
                ) from None
    return arrays
