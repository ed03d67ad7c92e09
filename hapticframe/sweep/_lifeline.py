"""A sweep worker's tie to the sweep's process: the worker ends when the sweep ends, however
it ends (``kill -9`` included).

A local pool's workers are children of multiprocessing's fork server, not of the sweep, and
each holds a copy of the pipe end whose closing tells the fork server that the sweep has
gone; so the fork server, the workers and the resource tracker all wait on each other.
Asking whether the sweep's process id still exists (``os.kill(pid, 0)``) is not enough: a
killed sweep whose own parent has not reaped it yet (``subprocess.run(capture_output=True)``
reads its pipes to the end first) is a zombie, and a zombie's id exists. So a worker
watches the sweep's process through a pidfd (readable once the process has exited,
reaped or not), or where there is none reads its state from ``/proc`` (``Z``: gone), and
asks Linux to kill it with its own parent. Once the workers have gone, the fork server
reads the end of its pipe and exits, and so does the resource tracker.
"""

from __future__ import annotations

import ctypes
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable

__all__ = ["die_with_parent", "process_alive", "watch_process"]

#: Linux's prctl option that sends a signal to this process when its parent ends.
_PR_SET_PDEATHSIG = 1
#: Seconds between two looks at the watched process where there is no pidfd.
POLL_S = 0.5


def die_with_parent() -> bool:
    """Ask Linux to SIGKILL this process when its parent ends (False where it cannot)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        # prctl is variadic: unsigned longs, as the kernel reads them.
        return int(libc.prctl(_PR_SET_PDEATHSIG, ctypes.c_ulong(signal.SIGKILL),
                              ctypes.c_ulong(0), ctypes.c_ulong(0), ctypes.c_ulong(0))) == 0
    except (OSError, AttributeError):
        return False


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` is running: a zombie (ended, not reaped yet) is not."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            # "pid (comm) state ...": comm may hold spaces and parentheses.
            state = stat.read().rsplit(b")", 1)[1].split()[0]
        return state not in (b"Z", b"X", b"x")
    except FileNotFoundError:
        return False
    except (OSError, IndexError):  # no /proc here: existence is all there is to ask
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except OSError:  # exists, owned by another user
            return True
        return True


def _open_pidfd(pid: int) -> int | None:
    """A pidfd of ``pid`` (Linux 5.3 and later); None where there is none.

    Raises
    ------
    ProcessLookupError
        When ``pid`` has already been reaped.
    """
    opener: Callable[[int], int] | None = getattr(os, "pidfd_open", None)
    if opener is None:
        return None
    try:
        return opener(pid)
    except ProcessLookupError:
        raise
    except OSError:  # an old kernel, or a sandbox that refuses the call
        return None


def watch_process(pid: int, on_gone: Callable[[], object] = lambda: os._exit(1), *,
                  poll_s: float = POLL_S) -> threading.Thread:
    """Call ``on_gone`` (default: end this process at once) from a daemon thread once
    process ``pid`` has ended, zombie or reaped; returns the started thread."""
    try:
        pidfd = _open_pidfd(pid)
    except ProcessLookupError:
        pidfd = None
        poll_s = 0.0  # already gone: the first look says so

    def watch() -> None:
        if pidfd is not None:
            select.select([pidfd], [], [])  # readable once the process has exited
        else:
            while process_alive(pid):
                time.sleep(poll_s)
        on_gone()

    thread = threading.Thread(target=watch, name=f"watch-process-{pid}", daemon=True)
    thread.start()
    return thread
