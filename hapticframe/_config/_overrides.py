"""``--set PATH=VALUE``: change one value of an experiment from the command line.

An override is applied to the loaded file's plain data before validation, so a bad value
is refused exactly as it would be in the file, at the same line and dotted path, with a
note that the value came from ``--set``. ``PATH`` is either

* a dotted path as error messages write it: ``maps[0].config.hinge_spacing_m``,
  ``run.max_movements``, ``seed``, ``scene.region.x_max_m``; or
* a component id and a field of that component's ``config``: ``bhm.hinge_spacing_m`` stands
  for ``maps[<index of bhm>].config.hinge_spacing_m``.

A path whose first part is a top-level key of an experiment (``run``, ``scene``, ``seed``,
``maps``, ...) is the first form; an id that is also a top-level key is ambiguous and
refused (write the list path). ``VALUE`` is read as YAML with the file loader's rules (plain
data only): ``0.025``, ``true``, ``null``, ``[0.1, 0.2]``, ``{x_min_m: 0, x_max_m: 1}``.

Missing mappings along the path are created (``bhm.kernel.length_scale_m`` on a component
without ``kernel``); a list index must exist. The validated
:class:`~hapticframe.Experiment` records what was set (:attr:`Experiment.overrides`), and
``run.json`` and ``train.json`` carry it as ``overrides``.
"""

from __future__ import annotations

import copy
import dataclasses
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, overload

from hapticframe._config._load import LoadedFile, join_path, load_text
from hapticframe._errors import ExperimentError, Issue, UsageError, shown
from hapticframe._kind import Kind

__all__ = [
    "AppliedOverride",
    "Override",
    "apply_overrides",
    "parse_override",
    "parse_overrides",
    "parse_value_list",
    "validate_with_overrides",
]

#: One part of a path: a key, then any number of ``[index]``.
_PART = re.compile(r"([^.\[\]]+)((?:\[\d+\])*)")
_INDEX = re.compile(r"\[(\d+)\]")

#: Keys at the top level of every experiment file besides the component lists.
_ROOT_KEYS = frozenset({"schema_version", "name", "description", "seed", "scene", "run"})
_SECTIONS = frozenset(kind.section for kind in Kind)


@dataclass(frozen=True)
class Override:
    """One ``--set PATH=VALUE`` as given: ``path`` as written, ``value`` as parsed."""

    path: str
    value: Any
    text: str

    def __str__(self) -> str:
        return self.text


@dataclass(frozen=True)
class AppliedOverride:
    """An override resolved against a file: where it went, and what it replaced.

    ``previous`` is the file's own value, ``None`` when the file did not hold the key
    (``had_value`` False: the plugin's default applied).
    """

    text: str
    path: str
    value: Any
    previous: Any
    had_value: bool

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, as ``run.json`` records it."""
        return {"set": self.text, "path": self.path, "value": self.value,
                "file_value": self.previous if self.had_value else None,
                "in_file": self.had_value}


def _split(path: str, where: str) -> list[str | int]:
    """``maps[0].config.x`` as ``["maps", 0, "config", "x"]``."""
    parts: list[str | int] = []
    for chunk in path.split("."):
        match = _PART.fullmatch(chunk)
        if match is None:
            raise UsageError(f"{where}: {shown(path)} is not a dotted path such as "
                             "'maps[0].config.hinge_spacing_m' or 'bhm.hinge_spacing_m'")
        parts.append(match.group(1))
        parts.extend(int(i) for i in _INDEX.findall(match.group(2)))
    return parts


def parse_value(text: str, where: str) -> Any:
    """``text`` read as YAML with the experiment loader's rules (plain data only)."""
    if not text.strip():
        raise UsageError(f"{where}: no value after '=' (write null for none)")
    try:
        return load_text(text, where, ".yaml").data
    except ExperimentError as exc:
        reason = exc.issues[0].message if exc.issues else str(exc)
        raise UsageError(f"{where}: the value {shown(text)} is not YAML: {reason}") from None


def parse_override(text: str) -> Override:
    """One ``PATH=VALUE``; raises :class:`UsageError` naming the option when malformed."""
    where = f"--set {shown(text)}"
    path, sep, value = text.partition("=")
    path = path.strip()
    if not sep or not path:
        raise UsageError(f"{where}: write PATH=VALUE, e.g. bhm.hinge_spacing_m=0.025 or "
                         "run.max_movements=10")
    _split(path, where)
    return Override(path, parse_value(value, where), text)


def parse_overrides(texts: Iterable[str | Override] | None) -> tuple[Override, ...]:
    """Every ``--set`` of a command (already parsed ones pass through)."""
    return tuple(t if isinstance(t, Override) else parse_override(t) for t in texts or ())


def parse_value_list(text: str, where: str) -> list[Any]:
    """``V1,V2,...`` (a ``--vary`` list) read as one YAML flow sequence, so that a value may
    itself be a list or a quoted string holding a comma."""
    if not text.strip():
        raise UsageError(f"{where}: no values after '='")
    try:
        values = load_text(f"[{text}]", where, ".yaml").data
    except ExperimentError as exc:
        reason = exc.issues[0].message if exc.issues else str(exc)
        raise UsageError(f"{where}: {shown(text)} is not a comma-separated list of YAML "
                         f"values: {reason}") from None
    if not isinstance(values, list) or not values:
        raise UsageError(f"{where}: no values after '='")
    return values


def _component_index(data: dict[str, Any]) -> dict[str, tuple[str, int]]:
    """Component id to (section, index) in the raw data."""
    found: dict[str, tuple[str, int]] = {}
    for section in sorted(_SECTIONS):
        entries = data.get(section)
        if not isinstance(entries, list):
            continue
        for index, entry in enumerate(entries):
            if isinstance(entry, dict) and isinstance(entry.get("id"), str):
                found.setdefault(entry["id"], (section, index))
    return found


def resolve_path(data: Any, override: Override) -> list[str | int]:
    """The file path (as parts) that ``override`` names in ``data``."""
    where = f"--set {shown(override.text)}"
    parts = _split(override.path, where)
    head = parts[0]
    components = _component_index(data) if isinstance(data, dict) else {}
    is_root = head in _ROOT_KEYS or head in _SECTIONS
    if isinstance(head, str) and head in components:
        if is_root:
            section, index = components[head]
            raise UsageError(
                f"{where}: {head!r} is both a component id and a top-level key; write the "
                f"list path, e.g. {section}[{index}].config.{'.'.join(map(str, parts[1:]))}")
        if len(parts) < 2:
            raise UsageError(f"{where}: name a field of the config of {head!r}, e.g. "
                             f"{head}.FIELD=VALUE")
        section, index = components[head]
        return [section, index, "config", *parts[1:]]
    if is_root:
        return parts
    ids = ", ".join(sorted(components)) or "none"
    raise UsageError(
        f"{where}: {shown(head)} is neither a component id (the file's: {ids}) nor a "
        f"top-level key ({', '.join(sorted(_ROOT_KEYS | _SECTIONS))})")


def _dotted(parts: Sequence[str | int]) -> str:
    dotted = ""
    for part in parts:
        dotted = join_path(dotted, part)
    return dotted


def _assign(data: Any, parts: Sequence[str | int], value: Any, where: str) -> tuple[Any, bool]:
    """Set ``value`` at ``parts`` inside ``data`` (changed in place); the previous value."""
    node = data
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        here = _dotted(parts[:depth]) or "the top level"
        if isinstance(part, int):
            if not isinstance(node, list):
                raise UsageError(f"{where}: {here} is not a list, so [{part}] names nothing")
            if part >= len(node):
                raise UsageError(f"{where}: {here} has {len(node)} entries; [{part}] is past "
                                 "its end")
            if last:
                previous = node[part]
                node[part] = value
                return previous, True
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise UsageError(f"{where}: {here} holds {type(node).__name__}, not a mapping, "
                             f"so it has no key {part!r}")
        if last:
            had = part in node
            previous = node.get(part)
            node[part] = value
            return previous, had
        if node.get(part) is None:
            node[part] = {}  # a missing mapping along the path (the plugin's defaults)
        node = node[part]
    raise AssertionError("unreachable: a path has at least one part")


def _as_loaded(loaded: LoadedFile | Mapping[str, Any], source: str) -> LoadedFile:
    if isinstance(loaded, LoadedFile):
        return loaded
    return LoadedFile(source, dict(loaded), {})


@overload
def apply_overrides(
    loaded: LoadedFile, overrides: Iterable[str | Override]
) -> tuple[LoadedFile, tuple[AppliedOverride, ...]]: ...


@overload
def apply_overrides(
    loaded: Mapping[str, Any], overrides: Iterable[str | Override]
) -> tuple[dict[str, Any], tuple[AppliedOverride, ...]]: ...


def apply_overrides(
    loaded: LoadedFile | Mapping[str, Any], overrides: Iterable[str | Override]
) -> tuple[Any, tuple[AppliedOverride, ...]]:
    """A copy of ``loaded`` with ``overrides`` applied in order, and where each went.

    ``loaded`` is a loaded file (a copy of it comes back) or an experiment mapping built in
    code (a changed deep copy comes back); ``overrides`` are ``PATH=VALUE`` texts or
    parsed :class:`Override` records.

    Raises
    ------
    UsageError
        An override is malformed or names nothing in the file (exit status 2).
    """
    if not isinstance(loaded, LoadedFile):
        changed, records = apply_overrides(_as_loaded(loaded, "<experiment>"), overrides)
        return (changed.data if records else copy.deepcopy(dict(loaded))), records
    parsed = parse_overrides(overrides)
    if not parsed:
        return loaded, ()
    if not isinstance(loaded.data, dict):
        raise UsageError(f"--set: {loaded.path} does not hold a mapping to set values in")
    data = copy.deepcopy(loaded.data)
    applied: list[AppliedOverride] = []
    for override in parsed:
        parts = resolve_path(data, override)
        previous, had = _assign(data, parts, copy.deepcopy(override.value),
                                f"--set {shown(override.text)}")
        applied.append(AppliedOverride(override.text, _dotted(parts), override.value,
                                       previous, had))
    return LoadedFile(loaded.path, data, dict(loaded.lines)), tuple(applied)


def _noted(issue: Issue, applied: Sequence[AppliedOverride]) -> Issue:
    """``issue`` with a note naming the ``--set`` that put the value there, if any did."""
    for override in reversed(applied):  # the last override of a path wins
        target = override.path
        if issue.path == target or issue.path.startswith((target + ".", target + "[")):
            return dataclasses.replace(
                issue, message=f"{issue.message} (the value came from --set {override.text})")
    return issue


def validate_with_overrides(
    loaded: LoadedFile | Mapping[str, Any], overrides: Iterable[str | Override] = (), *,
    source: str = "<experiment>", **kwargs: Any
) -> Any:
    """:func:`~hapticframe._config.validate_data` on ``loaded`` (a loaded file, or an
    experiment mapping named ``source``) with ``overrides`` applied; ``kwargs`` go to it.

    Errors are located as in the file (the line of the key the override replaced, or of
    its nearest parent) and say which ``--set`` gave the value; the returned
    :class:`~hapticframe.Experiment` records the overrides (``overrides``).
    """
    from hapticframe._config import validate_data

    changed, applied = apply_overrides(_as_loaded(loaded, source), overrides)
    try:
        experiment = validate_data(changed, **kwargs)
    except ExperimentError as exc:
        if not applied:
            raise
        raise ExperimentError(exc.file, [_noted(i, applied) for i in exc.issues]) from None
    if not applied:
        return experiment
    return dataclasses.replace(experiment,
                               overrides=tuple(a.as_dict() for a in applied))
