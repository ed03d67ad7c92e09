"""Exceptions with exit codes and located messages.

The CLI turns a :class:`HapticframeError` into one message and its :attr:`exit_code`
(2: bad input or usage, 1: failure while running, 130 or 143: interrupted by SIGINT or
SIGTERM); anything else is a bug and is reported
as such (``--debug`` shows the traceback).

Messages echo what users wrote (a key, a plugin type, a value), so every message is
bounded: a long run of characters is cut to its first :data:`KEEP_CHARS` and the count
(``'xxxx…(1048576 characters)'``), a line to :data:`MAX_LINE_CHARS`, a message to
:data:`MAX_LINES` lines; an :class:`ExperimentError` shows its first :data:`MAX_ISSUES`
problems. A 1 MB unknown ``type`` thus gives a one-line message, not a megabyte.
"""

from __future__ import annotations

import re
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
    "bound_text",
    "shown",
]

#: Characters kept of a value, a long word or a long line that is cut.
KEEP_CHARS = 60
#: A run of characters without a space or a path separator longer than this is cut (a
#: file's path stays whole: each of its parts is a word).
LONG_WORD_CHARS = 200
#: A line longer than this is cut.
MAX_LINE_CHARS = 2000
#: A message longer than this many lines is cut.
MAX_LINES = 100
#: Problems an :class:`ExperimentError` lists; the rest are counted.
MAX_ISSUES = 50

# Anchored at a word's start, so a line of short words is scanned once, not once a character.
_LONG_WORD = re.compile(rf"(?<![^\s/\\])[^\s/\\]{{{LONG_WORD_CHARS + 1},}}")


def _cut_word(match: re.Match[str]) -> str:
    word = match.group()
    body = word.rstrip(";,:.)")  # the punctuation after a value stays: "'xxx…(N characters);"
    return _cut(body) + word[len(body):]


def _cut(text: str, keep: int = KEEP_CHARS) -> str:
    return f"{text[:keep]}…({len(text)} characters)"


def shown(value: object, keep: int = KEEP_CHARS) -> str:
    """``repr(value)``, cut to its first ``keep`` characters and its length when longer.

    For messages that echo a user's value: ``f"unknown type {shown(name)}"``.
    """
    text = repr(value)
    return text if len(text) <= keep + 20 else _cut(text, keep)


def bound_text(text: str) -> str:
    """``text`` with long words, long lines and many lines cut (see the module's notes).

    Idempotent: a bounded text is returned unchanged.
    """
    if len(text) <= LONG_WORD_CHARS:  # the common case: nothing to cut
        return text
    lines = text.split("\n")
    extra = len(lines) - MAX_LINES
    if extra > 0:
        lines = [*lines[:MAX_LINES], f"…({extra} more lines)"]
    out = []
    for line in lines:
        if len(line) > LONG_WORD_CHARS:
            line = _LONG_WORD.sub(_cut_word, line)
            if len(line) > MAX_LINE_CHARS:
                line = _cut(line, MAX_LINE_CHARS)
        out.append(line)
    return "\n".join(out)


class HapticframeError(Exception):
    """Base class of the errors hapticframe reports to users."""

    exit_code: int = 1

    def __str__(self) -> str:
        # Bounded where it is printed, whatever a message echoes (see the module's notes).
        return bound_text(super().__str__())


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
        """``file:line: path: message``, with echoed values bounded (:func:`bound_text`)."""
        where = file if self.line is None else f"{file}:{self.line}"
        location = f" {_bound_path(self.path)}:" if self.path else ""
        return bound_text(f"{where}:{location} {self.message}")


_LONG_SEGMENT = re.compile(rf"[^.\[\]]{{{KEEP_CHARS + 21},}}")


def _bound_path(path: str) -> str:
    """A dotted path with each long key cut, so the path's shape stays readable."""
    if len(path) <= KEEP_CHARS + 20:
        return path
    return _LONG_SEGMENT.sub(lambda m: _cut(m.group()), path)


class ExperimentError(HapticframeError):
    """An experiment file is invalid; carries every problem found, each located."""

    exit_code = 2

    def __init__(self, file: str, issues: list[Issue]) -> None:
        self.file = file
        self.issues = issues
        super().__init__(self.render())

    def render(self) -> str:
        """Every problem on its own line (the first :data:`MAX_ISSUES`; the rest counted)."""
        lines = [issue.render(self.file) for issue in self.issues[:MAX_ISSUES]]
        if len(self.issues) > MAX_ISSUES:
            lines.append(f"…and {len(self.issues) - MAX_ISSUES} more problems")
        if len(self.issues) > 1:
            lines.insert(0, f"{self.file}: {len(self.issues)} problems")
        return "\n".join(lines)
