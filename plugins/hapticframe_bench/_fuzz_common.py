"""What every family of ``hapticframe bench fuzz`` shares: a case, its outcome, running a
command in a child process, and the checks that tell a clean end from a finding.

A case ends in one of these ways:

* ``refused``: exit 2 with a message that names what it refused (a file, directory, topic or
  setting): the user can act on it;
* ``ran`` / ``failed_clean``: exit 0 with real results, or exit 1 with one ``error:`` line;
* a finding: ``internal_error`` (a traceback or ``internal error:``), ``null_result`` (exit 0
  with a null or NaN result), ``lost_or_mixed`` (a finished run's files changed, files of two
  runs in one directory, a file deleted that hapticframe did not write), ``unlocated`` (a
  refusal that names nothing), ``timeout`` or ``unexpected`` (any other exit).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import resource
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "CLEAN",
    "FINDINGS",
    "Case",
    "CommandResult",
    "Outcome",
    "classify",
    "compare_snapshots",
    "hapticframe_command",
    "json_has_null_number",
    "snapshot",
]

#: How a case may end cleanly.
CLEAN = ("refused", "ran", "failed_clean", "accepted", "served")
#: The findings the bench counts (it must report 0 of each).
FINDINGS = ("internal_error", "null_result", "lost_or_mixed", "unlocated", "timeout",
            "unexpected")
#: A child command's limits: wall time and address space.
COMMAND_TIMEOUT_S = 120.0
COMMAND_MEMORY_BYTES = 6 * 1024**3
#: Files the project keeps in an output directory that are not results.
LOCK_FILE = ".hapticframe.lock"


@dataclass(frozen=True)
class Case:
    """One case of a family: what it does (``kind``), a readable ``change`` and its data."""

    family: str
    kind: str
    change: str
    data: dict[str, Any] = field(default_factory=dict, hash=False)


@dataclass
class Outcome:
    """What became of a case: a clean ``status`` (``ok`` True) or a finding, with why."""

    case: Case
    status: str
    ok: bool
    detail: str = ""
    seconds: float = 0.0


@dataclass(frozen=True)
class CommandResult:
    """A finished child command: exit status, output, and whether it ran out of time."""

    returncode: int
    stdout: str
    stderr: str
    timed_out: bool = False

    @property
    def last_line(self) -> str:
        lines = self.stderr.strip().splitlines()
        return lines[-1] if lines else ""


def _limit_memory() -> None:  # runs in the child before exec
    resource.setrlimit(resource.RLIMIT_AS, (COMMAND_MEMORY_BYTES, COMMAND_MEMORY_BYTES))


def hapticframe_command(args: list[str], *, cwd: Path | None = None,
                        timeout_s: float = COMMAND_TIMEOUT_S) -> CommandResult:
    """``python -m hapticframe ARGS`` in a child process (memory and time limited)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "HAPTICFRAME_MIN_FREE_MB": "1"}
    try:
        done = subprocess.run([sys.executable, "-m", "hapticframe", *args], cwd=cwd,
                              capture_output=True, text=True, timeout=timeout_s, env=env,
                              stdin=subprocess.DEVNULL,
                              preexec_fn=_limit_memory if os.name == "posix" else None,
                              check=False)
    except subprocess.TimeoutExpired as exc:
        def text(value: Any) -> str:
            return value.decode(errors="replace") if isinstance(value, bytes) else value or ""

        return CommandResult(-1, text(exc.stdout), text(exc.stderr), timed_out=True)
    return CommandResult(done.returncode, done.stdout, done.stderr)


def classify(case: Case, result: CommandResult, started: float, *,
             names: tuple[str, ...] = ()) -> Outcome:
    """The outcome of a command from its exit status and output alone.

    A refusal (exit 2) must name one of ``names`` (the inputs, or the directory it refused)
    in its message; an exit 0 is ``ran`` here, and the family checks its results.
    """
    seconds = time.perf_counter() - started
    last = result.last_line
    if result.timed_out:
        return Outcome(case, "timeout", False, f"no end within {COMMAND_TIMEOUT_S:g} s",
                       seconds)
    if "internal error" in result.stderr or "Traceback (most recent call last)" in \
            result.stderr:
        lines = [line for line in result.stderr.splitlines()
                 if "internal error" in line or "Error" in line]
        return Outcome(case, "internal_error", False, (lines[-1] if lines else last)[:300],
                       seconds)
    if result.returncode == 2:
        message = result.stderr
        if names and not any(name and name in message for name in names):
            return Outcome(case, "unlocated", False, f"exit 2 naming none of {names}: "
                           f"{last[:200]}", seconds)
        return Outcome(case, "refused", True, last[:300], seconds)
    if result.returncode == 1 and last.startswith("error:"):
        return Outcome(case, "failed_clean", True, last[:300], seconds)
    if result.returncode == 0:
        return Outcome(case, "ran", True, "", seconds)
    return Outcome(case, "unexpected", False, f"exit {result.returncode}: {last[:250]}",
                   seconds)


def snapshot(directory: Path) -> dict[str, str]:
    """Every file under ``directory`` (relative path → SHA-256), the lock file left out."""
    out: dict[str, str] = {}
    if not directory.is_dir():
        return out
    for path in sorted(directory.rglob("*")):
        if path.is_file() and not path.is_symlink() and path.name != LOCK_FILE:
            out[path.relative_to(directory).as_posix()] = hashlib.sha256(
                path.read_bytes()).hexdigest()
    return out


def compare_snapshots(before: dict[str, str], after: dict[str, str], *,
                      may_change: tuple[str, ...] = ()) -> list[str]:
    """What changed between two snapshots of a directory whose files must all stay: the
    deleted and the rewritten files (new files are not counted here), ``may_change``
    excepted."""
    problems = []
    for name, digest in before.items():
        if name in may_change:
            continue
        if name not in after:
            problems.append(f"{name} deleted")
        elif after[name] != digest:
            problems.append(f"{name} rewritten")
    return problems


def _refuse_constant(token: str) -> Any:
    raise ValueError(token)


def json_has_null_number(path: Path, keys: tuple[str, ...] = ()) -> str | None:
    """Why the JSON file at ``path`` is a null result (non-strict JSON with NaN or infinity,
    or one of ``keys`` null), or None."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"), parse_constant=_refuse_constant)
    except ValueError as exc:
        return f"{path.name} is not strict JSON ({exc})"
    except OSError as exc:
        return f"{path.name} cannot be read ({exc})"
    for key in keys:
        value = data.get(key) if isinstance(data, dict) else None
        if value is None or (isinstance(value, float) and not math.isfinite(value)):
            return f"{path.name}: {key} is {value!r}"
    return None
