"""Files written whole or not at all: a temporary name beside the target, renamed when done.

Everything hapticframe writes (results, figures, saved models, recordings' side files) goes
through these, so a killed or failed write never leaves a truncated file that looks complete.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe._errors import RunError

__all__ = [
    "TEMP_PREFIX",
    "OutputError",
    "atomic_path",
    "atomic_write",
    "output_error",
    "remove_quietly",
    "save_npz",
]

#: The prefix of every temporary file: a file of that name was left by a killed write.
TEMP_PREFIX = ".hftmp-"



class OutputError(RunError):
    """A result file or the ``--out`` directory cannot be written (disk full, no
    permission, read-only file system): the message names the file (exit status 1)."""

    def __init__(self, message: str, path: Path) -> None:
        super().__init__(message)
        self.path = path


def output_error(path: Path, exc: OSError, doing: str = "cannot write") -> OutputError:
    """An :class:`OutputError` naming ``path`` and saying what to do about ``exc``."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    code = errno.errorcode.get(exc.errno or 0, "")
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        hint = "; free some space or choose another --out"
    elif exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        hint = "; choose an --out directory you can write to"
    else:
        hint = ""
    return OutputError(f"{doing} {path}: {reason}{f' ({code})' if code else ''}{hint}", path)


def _temp_path(path: Path) -> Path:
    # Same folder (so the rename is atomic), same suffix (writers that name the format by
    # it, savefig and np.savez, keep working), a prefix a clean-up recognises.
    return path.with_name(f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}-{path.name}")


def remove_quietly(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    except OSError:  # a clean-up never hides the error that made it necessary
        pass


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed to ``path`` when the block
    ends without an error, removed when it raises (``path`` is then left as it was).

    For writers that take a file name (``savefig``, ``np.savez``, ``torch.save``); the
    temporary name ends with ``path``'s name, so its suffix is kept. An :class:`OSError`
    becomes an :class:`OutputError` naming ``path``.
    """
    target = Path(path)
    temp = _temp_path(target)
    try:
        yield temp
        _fsync(temp)  # the content reaches the disk before the name does
        os.replace(temp, target)
    except OSError as exc:
        remove_quietly(temp)
        raise output_error(target, exc) from exc
    except BaseException:
        remove_quietly(temp)
        raise


def atomic_write(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` (text is UTF-8) to ``path`` atomically; return ``path``.

    Raises :class:`OutputError` naming ``path`` when it cannot be written (disk full, no
    permission); ``path`` then keeps what it held before.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    target = Path(path)
    with atomic_path(target) as temp:
        fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            view = memoryview(raw)
            while view:
                written = os.write(fd, view)
                view = view[written:]
        finally:
            os.close(fd)
    return target


def save_npz(path: str | Path, compressed: bool = True, **arrays: Any) -> Path:
    """``np.savez_compressed`` (or ``np.savez``) to ``path`` atomically; return ``path``.

    ``path`` must end with ``.npz``. Raises :class:`OutputError` naming ``path`` when it
    cannot be written.
    """
    target = Path(path)
    if target.suffix != ".npz":
        raise ValueError(f"save_npz writes .npz files, not {target.name!r}")
    save = np.savez_compressed if compressed else np.savez
    with atomic_path(target) as temp:
        save(temp, **arrays)
    return target
