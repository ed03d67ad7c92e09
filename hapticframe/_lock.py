"""One writer per output directory: an OS lock held for the life of a command.

Every command that writes into a directory (``run``, ``train``, ``replay``, ``report``,
``recover``, ``sweep``, ``import-bag``) first takes :func:`lock_directory` on it. The lock
is an ``flock`` on the hidden file ``DIR/.hapticframe.lock``: the kernel releases it when
the process ends in any way (``kill -9`` included), so a killed command never leaves a
directory locked. A second writer is refused at once, never made to wait, with the holder
the file names (its pid, command line and start time, written by the holder after it took
the lock). The holder removes the file when it lets go; a file left by a killed holder is
not a lock, and the next writer takes it over.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from hapticframe._atomic import output_error
from hapticframe._errors import UsageError

__all__ = ["LOCK_FILE", "DirectoryBusy", "DirectoryLock", "lock_directory"]

#: The lock file's name inside a locked directory (hidden: never a result, never cleared).
LOCK_FILE = ".hapticframe.lock"
#: How many times a lock file replaced under the caller is tried again before giving up.
_ATTEMPTS = 5


class DirectoryBusy(UsageError):
    """Another process writes into the directory now (exit status 2)."""

    def __init__(self, message: str, holder: dict[str, Any]) -> None:
        super().__init__(message)
        self.holder = holder


@dataclass
class DirectoryLock:
    """A held lock; :meth:`release` (or leaving the ``with`` block) lets it go."""

    directory: Path
    fd: int | None

    @property
    def path(self) -> Path:
        return self.directory / LOCK_FILE

    @property
    def held(self) -> bool:
        return self.fd is not None

    def release(self) -> None:
        """Remove the lock file and let the lock go; idempotent.

        The file is removed while the lock is still held: a writer that opened it meanwhile
        finds, once it holds the lock, that the name no longer points at its file, and
        tries again (see :func:`lock_directory`).
        """
        if self.fd is None:
            return
        fd, self.fd = self.fd, None
        try:
            os.unlink(self.path)
        except OSError:
            pass  # gone already, or the directory is read-only now: the flock still ends
        os.close(fd)

    def __enter__(self) -> DirectoryLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _holder(command: str) -> dict[str, Any]:
    return {
        "pid": os.getpid(),
        "command": command,
        "argv": " ".join(sys.argv),
        "started_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }


def _read_holder(fd: int) -> dict[str, Any]:
    try:
        text = os.pread(fd, 64 * 1024, 0).decode("utf-8", "replace")
        holder = json.loads(text)
    except (OSError, ValueError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _describe(holder: dict[str, Any]) -> str:
    if not holder:
        return "another process (it has not said which yet)"
    parts = [f"{holder.get('command', 'a command')} (pid {holder.get('pid', '?')}"]
    if holder.get("started_utc"):
        parts.append(f", started {holder['started_utc']}")
    parts.append(")")
    argv = str(holder.get("argv") or "")
    if argv:
        parts.append(f": {argv if len(argv) <= 200 else argv[:200] + '…'}")
    return "".join(parts)


def lock_directory(directory: str | Path, command: str) -> DirectoryLock:
    """Lock the existing ``directory`` for this process's ``command`` (``"run"``, ...).

    Raises
    ------
    DirectoryBusy
        Another process holds the lock: the message names it (pid, command, start time).
    OutputError
        The lock file cannot be made (a read-only directory, no permission).
    """
    import fcntl

    directory = Path(directory)
    path = directory / LOCK_FILE
    for _ in range(_ATTEMPTS):
        try:
            # Never truncated on open: the holder's own description must survive a contender.
            fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as exc:
            raise output_error(path, exc, "cannot lock the directory:") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise DirectoryBusy(
                f"{directory} is in use by {_describe(holder)}; wait for it to end, or "
                "choose another directory", holder) from None
        except OSError as exc:
            os.close(fd)
            raise output_error(path, exc, "cannot lock the directory:") from exc
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the holder removed the file as we opened it: try the new one
            os.close(fd)
            continue
        text = json.dumps(_holder(command)).encode()
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, text, 0)
        except OSError:
            pass  # a full disk: the lock holds all the same, only its description is missing
        return DirectoryLock(directory, fd)
    raise UsageError(f"{directory}: its lock file keeps being replaced by other processes; "
                     "choose another directory")
