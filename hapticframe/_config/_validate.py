"""Validate an experiment file: plugin names, configs, and the component graph.

Every problem is reported with the file, the line and the dotted path, and all problems
of a file are reported at once.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from hapticframe._config._checks import core_checks, run_validators
from hapticframe._config._load import LoadedFile, join_path, load_file
from hapticframe._config._model import (
    CHANNEL_PATTERN,
    ID_PATTERN,
    TEXT_PATTERN,
    ComponentEntry,
    Experiment,
    build_experiment_model,
)
from hapticframe._config._strict import bool_issues
from hapticframe._errors import ExperimentError, Issue
from hapticframe._kind import Kind
from hapticframe._manager import PluginManager, get_plugin_manager, make_plugin_manager
from hapticframe._registry import Registry
from hapticframe._scene import NAME_PATTERN

__all__ = ["validate_data", "validate_file", "validate_mapping"]

_SECTIONS = {kind.section: kind for kind in Kind}
_DISCRIMINATORS = ("type", "shape")


def validate_file(
    path: str | Path,
    *,
    strict: bool = False,
    plugin_modules: Sequence[str] = (),
    plugin_dir: str | Path | None = None,
    command: str = "run",
) -> Experiment:
    """Load and validate an experiment file; raise :class:`ExperimentError` if it is invalid.

    ``plugin_modules`` names lab-local plugin modules to import first (trusted code chosen by
    the caller, like ``hapticframe run --plugin-module``), searched first in ``plugin_dir``.
    Experiment files themselves never name code to import. ``command`` is what the file is
    validated for, ``"run"`` or ``"train"`` (a file to train may hold untrained components).
    """
    loaded = load_file(path)
    return validate_data(loaded, strict=strict, plugin_modules=plugin_modules,
                         plugin_dir=plugin_dir, command=command)


def validate_mapping(
    data: Mapping[str, Any],
    *,
    source: str = "<experiment>",
    strict: bool = False,
    plugin_modules: Sequence[str] = (),
    plugin_dir: str | Path | None = None,
    command: str = "run",
) -> Experiment:
    """Validate an experiment given as a mapping (built in code rather than read from a file)."""
    return validate_data(LoadedFile(source, dict(data), {}), strict=strict,
                         plugin_modules=plugin_modules, plugin_dir=plugin_dir, command=command)


#: The experiment-file key that once named plugin modules; kept to say what to do instead.
_IMPORT_KEY = "plugin_modules"


def _plugin_manager(
    strict: bool, plugin_modules: Sequence[str], plugin_dir: str | Path | None
) -> PluginManager:
    if not plugin_modules:
        return make_plugin_manager(strict=True) if strict else get_plugin_manager()
    return make_plugin_manager(
        strict=strict, modules=list(plugin_modules),
        module_dir=None if plugin_dir is None else Path(plugin_dir).resolve(),
    )


def validate_data(
    loaded: LoadedFile, *, strict: bool = False, plugin_manager: PluginManager | None = None,
    plugin_modules: Sequence[str] = (), plugin_dir: str | Path | None = None,
    command: str = "run",
) -> Experiment:
    """Validate parsed experiment data (see :func:`validate_file`).

    Raises
    ------
    ExperimentError
        The data is not a valid experiment (every problem located).
    PluginImportError
        A module of ``plugin_modules`` fails to import.
    """
    file = loaded.path
    data = loaded.data
    if not isinstance(data, dict):
        raise ExperimentError(file, [Issue(
            "", "the top level must be a mapping with schema_version, name, seed and component "
            f"lists, not {type(data).__name__}", 1,
        )])
    if _IMPORT_KEY in data:
        raise ExperimentError(file, [Issue(
            _IMPORT_KEY, "experiment files never name code to import: install the plugin "
            "package (its entry point registers it), or have the person running the "
            "experiment name lab-local modules with `--plugin-module NAME`",
            loaded.line_of(_IMPORT_KEY),
        )])
    pm = plugin_manager or _plugin_manager(strict, plugin_modules, plugin_dir)
    registry = pm.registry
    issues, flagged = _check_types(loaded, registry)
    model_cls = build_experiment_model(registry)
    model = None
    booleans = [b for b in bool_issues(model_cls, loaded)
                if not any(b.path == f or b.path.startswith(f + ".") for f in flagged)]
    issues.extend(booleans)
    try:
        model = model_cls.model_validate(data)
    except ValidationError as exc:
        refused = {b.path for b in booleans}
        for error in exc.errors(include_url=False):
            issue = _issue_from_pydantic(error, loaded, registry)
            if issue.path in refused:
                continue  # said once: the boolean where a number belongs
            if not any(issue.path == f or issue.path.startswith(f + ".") for f in flagged):
                issues.append(issue)
    if model is not None and not issues:
        entries = _entries(model, registry)
        issues.extend(_check_graph(entries, loaded))
        issues.extend(_check_train_from(model.run.train_from, entries, loaded))
        if not issues:
            # The core's checks first; the plugins' validators read a consistent experiment
            # (and do not repeat, in their words, what the core has already refused).
            errors, warnings = core_checks(entries, model, loaded)
            issues.extend(errors)
            if not errors:
                plugin_errors, plugin_warnings = run_validators(entries, model, loaded, command)
                issues.extend(plugin_errors)
                warnings.extend(w for w in plugin_warnings if w.path not in
                                {c.path for c in warnings})
        if not issues:
            return Experiment(file, model, tuple(_build_order(entries)), registry, pm,
                              tuple(warnings))
    issues.sort(key=lambda i: (i.line or 0, i.path))
    raise ExperimentError(file, _dedupe(issues))


def _dedupe(issues: Iterable[Issue]) -> list[Issue]:
    seen, out = set(), []
    for issue in issues:
        if (issue.path, issue.message) not in seen:
            seen.add((issue.path, issue.message))
            out.append(issue)
    return out


def _check_types(loaded: LoadedFile, registry: Registry) -> tuple[list[Issue], set[str]]:
    """Unknown or unusable plugin types, with suggestions and install hints."""
    issues: list[Issue] = []
    flagged: set[str] = set()
    for section, kind in _SECTIONS.items():
        entries = loaded.data.get(section)
        if not isinstance(entries, list):
            continue
        for index, entry in enumerate(entries):
            where = join_path(section, index)
            if not isinstance(entry, dict) or not isinstance(entry.get("type"), str):
                continue  # the model reports the shape error
            name = entry["type"]
            line = loaded.line_of(join_path(where, "type"))
            if name not in registry.plugins[kind]:
                issues.append(Issue(f"{where}.type", registry.unknown_message(kind, name), line))
                flagged.add(where)
                if not registry.plugins[kind]:
                    flagged.add(section)  # the section must stay empty: said once is enough
                continue
            registered = registry.plugins[kind][name]
            conflict = [c for c in registry.conflicts if (c.kind, c.name) == (kind, name)]
            if conflict:
                issues.append(Issue(f"{where}.type", conflict[0].message(), line))
            missing = registered.missing_requirements
            if missing:
                hint = registered.spec.install_hint or "install the missing packages"
                issues.append(Issue(
                    f"{where}.type",
                    f"{kind} plugin {name!r} needs {', '.join(missing)}, which is not "
                    f"installed: {hint}",
                    line,
                ))
                flagged.add(where)
    return issues, flagged


def _issue_from_pydantic(error: Mapping[str, Any], loaded: LoadedFile, registry: Registry) -> Issue:
    loc = list(error["loc"])
    parts: list[str | int] = []
    raw: Any = loaded.data
    i = 0
    while i < len(loc):
        key = loc[i]
        if isinstance(key, str) and isinstance(raw, list | str | int | float):
            i += 1  # the label of a union's member (``tuple[...]``, a tag): not in the file
            continue
        parts.append(key)
        raw = raw.get(key) if isinstance(raw, dict) and isinstance(key, str) else (
            raw[key] if isinstance(raw, list) and isinstance(key, int) and key < len(raw) else None
        )
        # A tagged union adds the tag to the location: skip it.
        if (
            isinstance(key, int) and i + 1 < len(loc) and isinstance(raw, dict)
            and any(raw.get(d) == loc[i + 1] for d in _DISCRIMINATORS)
        ):
            i += 1
        i += 1
    dotted = ""
    for part in parts:
        dotted = join_path(dotted, part)
    kind = error["type"]
    message = str(error["msg"])
    if kind == "value_error":  # a validator's own sentence: pydantic's prefix adds nothing
        message = message.removeprefix("Value error, ")
    if kind == "extra_forbidden":
        message = f"unknown key {parts[-1]!r}" + _key_suggestion(parts, loaded, registry)
    elif kind == "missing":
        message = "required key is missing"
    elif kind == "literal_error" and parts == ["schema_version"]:
        message = (
            "schema_version must be 1 (this hapticframe reads version 1), got "
            f"{error.get('input')!r}"
        )
    elif kind == "string_pattern_mismatch" and error.get("ctx", {}).get("pattern") in _PATTERNS:
        shown = repr(error.get("input"))
        message = (f"{_PATTERNS[error['ctx']['pattern']]} "
                   f"(got {shown[:60]}{'...' if len(shown) > 60 else ''})")
    elif kind in ("int_type", "int_parsing") and isinstance(error.get("input"), bool | str):
        message = (f"must be an integer written as a number, not "
                   f"{type(error['input']).__name__} {error['input']!r:.60}")
    elif "input" in error and kind not in ("model_type", "dict_type", "list_type"):
        shown = repr(error["input"])
        message = f"{message} (got {shown[:60]}{'...' if len(shown) > 60 else ''})"
    return Issue(dotted, message, loaded.line_of(dotted))


#: What a string of each pattern must look like, said in words.
_PATTERNS = {
    ID_PATTERN: "an id is a letter followed by at most 63 letters, digits, '-' or '_'",
    CHANNEL_PATTERN: "a channel name is a letter or '_' followed by at most 63 letters, "
    "digits, '_', '.' or '-'",
    NAME_PATTERN: "a name is one line of 1 to 200 characters without control characters "
    "(NUL, newline, ...)",
    TEXT_PATTERN: "free text holds no control characters but tabs and newlines",
}


def _key_suggestion(parts: list[str | int], loaded: LoadedFile, registry: Registry) -> str:
    """Close names for an unknown key, from the model that holds it (any nesting level)."""
    key = str(parts[-1])
    valid = _keys_at(build_experiment_model(registry), parts[:-1], loaded.data)
    close = difflib.get_close_matches(key, valid, n=3, cutoff=0.5)
    if close:
        return "; did you mean " + " or ".join(repr(c) for c in close) + "?"
    if valid:
        return f"; valid keys: {', '.join(valid)}"
    return ""


def _keys_at(root: type[BaseModel], parents: Sequence[str | int], data: Any) -> list[str]:
    """The field names of the model found at ``parents`` (a dotted location in ``data``).

    The walk follows the annotations of the experiment model: optional fields, lists and
    tagged unions (picked by the raw entry's ``type`` or ``shape``) included. An empty list
    when the location holds no model (a free-form mapping, or an entry whose tag is unknown).
    """
    annotation: Any = root
    raw: Any = data
    for part in parents:
        annotation = _unwrap(annotation, raw)
        if isinstance(part, int):
            if get_origin(annotation) not in (list, tuple) or not get_args(annotation):
                return []
            annotation = get_args(annotation)[0]
            raw = raw[part] if isinstance(raw, list) and part < len(raw) else None
        else:
            if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
                return []
            field = annotation.model_fields.get(part)
            if field is None:
                return []
            annotation = field.annotation
            raw = raw.get(part) if isinstance(raw, dict) else None
    annotation = _unwrap(annotation, raw)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return list(annotation.model_fields)
    return []


def _unwrap(annotation: Any, raw: Any) -> Any:
    """Strip ``Annotated`` and ``None`` from a union; pick a tagged union's variant by ``raw``."""
    while True:
        if get_origin(annotation) is Annotated:
            annotation = get_args(annotation)[0]
            continue
        if get_origin(annotation) in (Union, UnionType):
            options = [a for a in get_args(annotation) if a is not type(None)]
            if len(options) == 1:
                annotation = options[0]
                continue
            return _variant_for(options, raw)
        return annotation


def _variant_for(options: Sequence[Any], raw: Any) -> Any:
    if not isinstance(raw, dict):
        return None
    for option in options:
        if not (isinstance(option, type) and issubclass(option, BaseModel)):
            continue
        for tag in _DISCRIMINATORS:
            field = option.model_fields.get(tag)
            if field is not None and get_origin(field.annotation) is Literal and (
                raw.get(tag) in get_args(field.annotation)
            ):
                return option
    return None


def _entries(model: BaseModel, registry: Registry) -> list[ComponentEntry]:
    entries = []
    for section, kind in _SECTIONS.items():
        for index, item in enumerate(getattr(model, section)):
            entries.append(ComponentEntry(
                kind, item.id, item.type, item.config, tuple(item.inputs),
                registry.plugins[kind][item.type], join_path(section, index),
            ))
    return entries


def _check_graph(entries: list[ComponentEntry], loaded: LoadedFile) -> list[Issue]:
    issues: list[Issue] = []
    by_id: dict[str, ComponentEntry] = {}
    for entry in entries:
        if entry.id in by_id:
            first = by_id[entry.id]
            issues.append(Issue(
                f"{entry.path}.id",
                f"duplicate id {entry.id!r} (first used at {first.path}, line "
                f"{loaded.line_of(first.path + '.id')})",
                loaded.line_of(f"{entry.path}.id"),
            ))
        else:
            by_id[entry.id] = entry
    for entry in entries:
        for j, name in enumerate(entry.inputs):
            where = join_path(f"{entry.path}.inputs", j)
            line = loaded.line_of(where)
            if name not in by_id:
                close = difflib.get_close_matches(name, list(by_id), n=3, cutoff=0.5)
                hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
                issues.append(
                    Issue(where, f"input {name!r} is not the id of any component{hint}", line)
                )
                continue
            source = by_id[name]
            if name == entry.id:
                issues.append(Issue(where, f"{entry.id!r} cannot be its own input", line))
                continue
            accepted = entry.registered.spec.inputs or ()  # never None once the spec is built
            if source.kind not in accepted:
                allowed = ", ".join(str(k) for k in accepted) or "nothing"
                issues.append(Issue(
                    where,
                    f"{entry.id!r} ({entry.kind} {entry.type!r}) cannot read {name!r}, a "
                    f"{source.kind}; it accepts: {allowed}",
                    line,
                ))
    if not issues:
        cycle = _find_cycle(entries)
        if cycle:
            first = by_id[cycle[0]]
            issues.append(Issue(
                f"{first.path}.inputs",
                "inputs form a cycle: " + " -> ".join(cycle + [cycle[0]]),
                loaded.line_of(f"{first.path}.inputs"),
            ))
    return issues


def _check_train_from(
    train_from: Mapping[str, str], entries: list[ComponentEntry], loaded: LoadedFile
) -> list[Issue]:
    """``run.train_from`` pairs a streamed sensor with a training-only sensor."""
    issues: list[Issue] = []
    sensors = {e.id for e in entries if e.kind is Kind.SENSOR}
    read_by = {name: e.id for e in entries for name in e.inputs}
    for target, source in train_from.items():
        where = f"run.train_from.{target}"
        line = loaded.line_of(where) or loaded.line_of("run.train_from")
        for role, name in (("key", target), ("value", source)):
            if name not in sensors:
                close = difflib.get_close_matches(name, sorted(sensors), n=3, cutoff=0.5)
                hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
                issues.append(
                    Issue(where, f"{role} {name!r} is not the id of a sensor{hint}", line)
                )
        if source == target:
            issues.append(Issue(where, f"sensor {target!r} cannot stand in for itself", line))
        elif source in train_from:
            issues.append(Issue(where, f"{source!r} is both streamed and a training sensor", line))
        elif source in read_by:
            issues.append(Issue(
                where,
                f"training sensor {source!r} is an input of {read_by[source]!r}; training "
                "sensors are only read while fitting, so no component may name them",
                line,
            ))
    return issues


def _find_cycle(entries: list[ComponentEntry]) -> list[str] | None:
    graph = {e.id: list(e.inputs) for e in entries}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in graph.get(node, []):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in graph:
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def _build_order(entries: list[ComponentEntry]) -> list[ComponentEntry]:
    """Inputs before their consumers; ties kept in data-flow (kind) then file order."""
    remaining = list(entries)
    done: set[str] = set()
    order: list[ComponentEntry] = []
    while remaining:
        for entry in remaining:
            if all(name in done for name in entry.inputs):
                order.append(entry)
                done.add(entry.id)
                remaining.remove(entry)
                break
        else:  # pragma: no cover - cycles are rejected before
            raise AssertionError("cycle in component graph")
    return order
