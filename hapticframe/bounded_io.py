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

HDF5 (h5py, imported only when used): :func:`open_hdf5` opens regular files only,
:func:`hdf5_child` and :func:`hdf5_members` look objects up link by link (soft links only
when they resolve inside the file, external links never), and :func:`read_hdf5_dataset`
refuses raw data stored outside the file and checks the dataspace before reading. Every
h5py failure (a damaged object header, a loop) becomes a :class:`BoundedReadError` naming
the object's path. ``hapticframe import``, the BOLT reader and the Keras reader use them.
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

__all__ = [
    "MAX_RECORDING_BYTES",
    "MAX_SOFT_LINKS",
    "BoundedReadError",
    "format_bytes",
    "hdf5_child",
    "hdf5_members",
    "open_hdf5",
    "open_regular",
    "read_hdf5_dataset",
    "read_npz",
]

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
                f"the path is {_kind(mode)}, not a regular file; hapticframe reads "
                "regular files only"
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
                    "unpickle, which hapticframe never does (allow_pickle=False); save numbers "
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


# --- HDF5 ----------------------------------------------------------------------------------
#
# h5py raises many kinds of exception for a damaged file (OSError, KeyError, RuntimeError,
# ValueError, TypeError, SystemError...), and follows soft and external links on every
# lookup. The helpers below open only regular files, look a child up link by link (hard
# links, and soft links that resolve inside the file; never external links), read only
# datasets whose raw data are inside the file, and check a dataset's declared size before
# its data are read.

#: Soft links followed, one after another, before a lookup is refused as a loop.
MAX_SOFT_LINKS = 8


def _h5py() -> Any:
    try:
        import h5py
    except ImportError:
        raise BoundedReadError("reading HDF5 needs h5py: pip install 'hapticframe[hdf5]'"
                               ) from None
    return h5py


def _h5_reason(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    return text if len(text) <= 200 else text[:200] + "…"


def open_hdf5(path: str | os.PathLike[str]) -> Any:
    """An ``h5py.File`` open for reading, when ``path`` is a regular HDF5 file.

    Raises
    ------
    FileNotFoundError
        When nothing is there.
    BoundedReadError
        When it is not a regular file (a FIFO, a device, a directory) or not readable HDF5.
    """
    h5py = _h5py()
    with open_regular(path):  # never blocks, and refuses all but regular files
        pass
    try:
        return h5py.File(path, "r", locking=False)
    except Exception as exc:  # h5py: OSError for most damage, others for some
        raise BoundedReadError(f"not a readable HDF5 file (not an HDF5 file, or a damaged "
                               f"one: {_h5_reason(exc)})"
                               ) from None


def hdf5_child(group: Any, name: str, _hops: dict[str, Any] | None = None) -> Any:
    """The object ``name`` names in ``group`` (one path component or several), or None.

    Each component is looked up link by link: a hard link is followed, a soft link only when
    its target resolves inside the file within :data:`MAX_SOFT_LINKS` hops, an external link
    never.

    Raises
    ------
    BoundedReadError
        An external link, a dangling soft link, a soft-link loop, or an object whose header
        cannot be read (the message gives the object's path in the file).
    """
    h5py = _h5py()
    # Soft links followed in this lookup (nested ones too), and the path first asked for.
    hops = {"n": 0, "asked": f"{group.name.rstrip('/')}/{name}"} if _hops is None else _hops
    node = group
    for part in [p for p in name.split("/") if p]:
        if not isinstance(node, h5py.Group):
            return None
        node = _follow(h5py, node, part, hops)
        if node is None:
            return None
    return node


def _follow(h5py: Any, group: Any, part: str, hops: dict[str, Any]) -> Any:
    where = f"{group.name.rstrip('/')}/{part}"
    via = ""  # the soft link's target, once one is followed
    while hops["n"] <= MAX_SOFT_LINKS:
        try:
            link = group.get(part, getlink=True)
        except Exception as exc:
            raise BoundedReadError(f"{where}: the link cannot be read ({_h5_reason(exc)})"
                                   ) from None
        if link is None and via:
            raise BoundedReadError(f"{hops['asked']} is a soft link to {via!r}, which is not "
                                   "in the file")
        if link is None:
            return None
        if isinstance(link, h5py.ExternalLink):
            raise BoundedReadError(
                f"{where} is an external link to {link.filename!r}; links outside the file "
                "are not followed: copy the data into the file")
        if isinstance(link, h5py.SoftLink):
            hops["n"] += 1
            target = via = str(link.path)
            parent, _, leaf = target.rstrip("/").rpartition("/")
            base = group.file if target.startswith("/") else group
            if not leaf:
                return group.file
            holder = hdf5_child(base, parent, hops) if parent else base
            if not isinstance(holder, h5py.Group):
                raise BoundedReadError(f"{where} is a soft link to {target!r}, which is not "
                                       "in the file")
            group, part = holder, leaf
            continue
        try:
            return group[part]
        except Exception as exc:
            raise BoundedReadError(f"{where}: the object cannot be read (a damaged object "
                                   f"header? {_h5_reason(exc)})") from None
    raise BoundedReadError(f"{hops['asked']}: its soft links lead through more than "
                           f"{MAX_SOFT_LINKS} others (a loop?)")


def hdf5_members(group: Any) -> list[tuple[str, Any]]:
    """``(name, object)`` for every member of ``group``, in name order, by
    :func:`hdf5_child` (dangling, looping and external links refused)."""
    try:
        names = sorted(group.keys())
    except Exception as exc:
        raise BoundedReadError(f"{group.name}: the group's members cannot be listed "
                               f"({_h5_reason(exc)})") from None
    return [(name, hdf5_child(group, name)) for name in names]


def read_hdf5_dataset(dataset: Any, max_cells: int, kinds: str = "biuf") -> NDArray[Any]:
    """The values of ``dataset``, once its storage and declared size are found acceptable.

    Raises
    ------
    BoundedReadError
        Raw data stored outside the file (external storage or a virtual dataset), a dtype
        whose kind is not in ``kinds``, more than ``max_cells`` values declared (the
        dataspace, checked before anything is read), or data that cannot be read.
    """
    where = dataset.name
    try:
        external = dataset.external
        virtual = dataset.is_virtual
        shape = tuple(int(n) for n in (dataset.shape or ()))
        dtype = dataset.dtype
    except Exception as exc:
        raise BoundedReadError(f"{where}: the dataset's header cannot be read "
                               f"({_h5_reason(exc)})") from None
    if external or virtual:
        raise BoundedReadError(
            f"{where}: its raw data are stored outside the file "
            f"({'a virtual dataset' if virtual else 'external storage'}); datasets are read "
            "from inside the file only")
    if dtype.kind not in kinds:
        raise BoundedReadError(f"{where}: {dtype} is not numeric")
    cells = math.prod(shape)
    if cells > max_cells:
        raise BoundedReadError(
            f"{where}: declares {' x '.join(map(str, shape))} = {cells} values, more than "
            f"the {max_cells} still allowed for this file")
    try:
        return np.asarray(dataset[()])
    except Exception as exc:
        raise BoundedReadError(f"{where}: the data cannot be read ({_h5_reason(exc)})"
                               ) from None
