"""Exceptions with exit codes and located messages.

The CLI turns a :class:`HapticframeError` into one message and its :attr:`exit_code`
(2: bad input or usage, 1: failure while running, 130 or 143: interrupted by SIGINT or
SIGTERM); anything else is a bug and is reported
as such (``--debug`` shows the traceback).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

__all__ = [
    "ExperimentError",
    "HapticframeError",
    "Issue",
    "PluginConflictError",
    "PluginError",
    "PluginImportError",
    "RunError",
    "RunInterrupted",
    "UsageError",
]


class HapticframeError(Exception):
    """Base class of the errors hapticframe reports to users."""

    exit_code: int = 1


class UsageError(HapticframeError):
    """Bad command-line usage or arguments."""

    exit_code = 2


class PluginError(HapticframeError):
    """A plugin is malformed or cannot be used."""

    exit_code = 2


class PluginConflictError(PluginError):
    """Two distributions register one name for one kind."""


class PluginImportError(PluginError):
    """A plugin's implementation or entry point cannot be imported."""

    exit_code = 1


class RunError(HapticframeError):
    """A failure while an experiment runs."""

    exit_code = 1


class RunInterrupted(HapticframeError):
    """A run stopped by a signal: Ctrl-C (SIGINT) or SIGTERM.

    Its exit status is the shell's for a process ended by that signal, 128 + the signal
    number: 130 for SIGINT, 143 for SIGTERM. ``run.json`` records ``status: interrupted``
    and the signal's name.
    """

    _EXIT_CODES: ClassVar[dict[str, int]] = {"SIGINT": 130, "SIGTERM": 143}

    def __init__(self, signal_name: str) -> None:
        self.signal_name = signal_name
        self.exit_code = self._EXIT_CODES.get(signal_name, 1)
        super().__init__(f"the run was interrupted ({signal_name})")


@dataclass(frozen=True)
class Issue:
    """One problem in an experiment file.

    Parameters
    ----------
    path : str
        Dotted location such as ``maps[0].config.hinge_spacing_m`` (``""`` for the file).
    message : str
    line : int or None
        1-based line in the file, when known.
    """

    path: str
    message: str
    line: int | None = None

    def render(self, file: str) -> str:
        where = file if self.line is None else f"{file}:{self.line}"
        location = f" {self.path}:" if self.path else ""
        return f"{where}:{location} {self.message}"


class ExperimentError(HapticframeError):
    """An experiment file is invalid; carries every problem found, each located."""

    exit_code = 2

    def __init__(self, file: str, issues: list[Issue]) -> None:
        self.file = file
        self.issues = issues
        super().__init__(self.render())

    def render(self) -> str:
        lines = [issue.render(self.file) for issue in self.issues]
        if len(lines) > 1:
            lines.insert(0, f"{self.file}: {len(self.issues)} problems")
        return "\n".join(lines)
