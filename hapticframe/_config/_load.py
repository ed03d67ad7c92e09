"""Read experiment files (YAML, JSON, TOML) into plain data with line numbers.

YAML is composed into nodes with PyYAML's safe loader and converted here, so that only
plain data comes out (no ``!!python`` tags: only the standard scalar tags are accepted),
every mapping key gets its line number, duplicate keys are errors (PyYAML silently keeps
the last), and aliases cannot expand into a "billion laughs": the number of values an
alias expands to is capped.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .._errors import ExperimentError, Issue

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["LoadedFile", "load_file", "load_text"]

MAX_FILE_BYTES = 4 * 1024 * 1024
MAX_VALUES = 200_000  # values after alias expansion
MAX_DEPTH = 64

_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
}
_MAP_TAG = "tag:yaml.org,2002:map"
_SEQ_TAG = "tag:yaml.org,2002:seq"


@dataclass
class LoadedFile:
    """Plain data from an experiment file and the line of each dotted path."""

    path: str
    data: Any
    lines: dict[str, int] = field(default_factory=dict)

    def line_of(self, dotted: str) -> int | None:
        """The line of ``dotted`` or of its nearest parent that has one."""
        probe = dotted
        while True:
            if probe in self.lines:
                return self.lines[probe]
            if not probe:
                return None
            cut = max(probe.rfind("."), probe.rfind("["))
            probe = probe[:cut] if cut > 0 else ""


def join_path(parent: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{parent}[{key}]"
    return f"{parent}.{key}" if parent else str(key)


class _YamlConverter:
    def __init__(self, file: str) -> None:
        self.file = file
        self.lines: dict[str, int] = {}
        self.count = 0
        self.constructor = yaml.SafeLoader("")

    def fail(self, node: yaml.Node, message: str) -> ExperimentError:
        return ExperimentError(self.file, [Issue("", message, node.start_mark.line + 1)])

    def convert(self, node: yaml.Node, path: str, depth: int) -> Any:
        self.count += 1
        if self.count > MAX_VALUES:
            raise self.fail(node, f"the document expands to more than {MAX_VALUES} values "
                                  "(an alias bomb?)")
        if depth > MAX_DEPTH:
            raise self.fail(node, f"nesting deeper than {MAX_DEPTH} levels")
        if path not in self.lines:
            self.lines[path] = node.start_mark.line + 1
        if isinstance(node, yaml.ScalarNode):
            if node.tag == "tag:yaml.org,2002:timestamp":
                return node.value  # dates stay text; no field here is a date
            if node.tag not in _SCALAR_TAGS:
                raise self.fail(node, f"tag {node.tag!r} is not allowed: experiment files "
                                      "hold plain data only")
            try:
                return self.constructor.construct_object(node, deep=True)
            except yaml.YAMLError as exc:
                raise self.fail(node, str(exc).splitlines()[0]) from None
        if isinstance(node, yaml.SequenceNode):
            if node.tag != _SEQ_TAG:
                raise self.fail(node, f"tag {node.tag!r} is not allowed")
            return [self.convert(item, join_path(path, i), depth + 1)
                    for i, item in enumerate(node.value)]
        if isinstance(node, yaml.MappingNode):
            if node.tag != _MAP_TAG:
                raise self.fail(node, f"tag {node.tag!r} is not allowed")
            out: dict[str, Any] = {}
            for key_node, value_node in node.value:
                if (not isinstance(key_node, yaml.ScalarNode)
                        or key_node.tag == "tag:yaml.org,2002:merge"):
                    raise self.fail(key_node, "keys must be plain strings (no merge keys)")
                key = self.convert(key_node, path, depth + 1)
                if not isinstance(key, str):
                    key = str(key)
                if key in out:
                    raise self.fail(key_node, f"duplicate key {key!r}")
                child = join_path(path, key)
                self.lines[child] = key_node.start_mark.line + 1
                out[key] = self.convert(value_node, child, depth + 1)
            return out
        raise self.fail(node, f"unsupported YAML node {type(node).__name__}")


def _yaml_lines(text: str, file: str) -> tuple[Any, dict[str, int]]:
    try:
        loader = yaml.SafeLoader(text)
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        message = " ".join(str(part) for part in (exc.context, exc.problem) if part)
        raise ExperimentError(file, [Issue("", f"YAML syntax error: {message}", line)]) from None
    except yaml.YAMLError as exc:
        raise ExperimentError(file, [Issue("", f"YAML error: {exc}")]) from None
    if node is None:
        return None, {}
    converter = _YamlConverter(file)
    data = converter.convert(node, "", 0)
    return data, converter.lines


def load_text(text: str, file: str, suffix: str) -> LoadedFile:
    """Parse ``text`` by the file suffix (``.yaml``/``.yml``, ``.json``, ``.toml``)."""
    suffix = suffix.lower()
    if suffix == ".json":
        try:
            data = json.loads(text, object_pairs_hook=_no_duplicate_pairs)
        except json.JSONDecodeError as exc:
            raise ExperimentError(
                file, [Issue("", f"JSON syntax error: {exc.msg}", exc.lineno)]
            ) from None
        except ValueError as exc:
            raise ExperimentError(file, [Issue("", str(exc))]) from None
        try:  # JSON is YAML, so the YAML pass can tell line numbers.
            _, lines = _yaml_lines(text, file)
        except ExperimentError:
            lines = {}
        return LoadedFile(file, data, lines)
    if suffix == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ExperimentError(file, [Issue("", f"TOML syntax error: {exc}")]) from None
        return LoadedFile(file, data, {})
    if suffix in (".yaml", ".yml"):
        data, lines = _yaml_lines(text, file)
        return LoadedFile(file, data, lines)
    raise ExperimentError(
        file, [Issue("", f"unknown file type {suffix!r}: use .yaml, .yml, .json or .toml")]
    )


def _no_duplicate_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"duplicate key {key!r}")
        out[key] = value
    return out


def load_file(path: str | Path) -> LoadedFile:
    """Read and parse an experiment file, raising :class:`ExperimentError` when it is unusable."""
    p = Path(path)
    file = str(path)
    try:
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ExperimentError(
                file, [Issue("", f"file is {size} bytes; the limit is {MAX_FILE_BYTES}")]
            )
        raw = p.read_bytes()
    except FileNotFoundError:
        raise ExperimentError(file, [Issue("", "no such file")]) from None
    except IsADirectoryError:
        raise ExperimentError(file, [Issue("", "is a directory, not an experiment file")]) from None
    except OSError as exc:
        raise ExperimentError(file, [Issue("", f"cannot read: {exc.strerror}")]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ExperimentError(
            file, [Issue("", f"not UTF-8 text (byte {exc.start} is 0x{raw[exc.start]:02x})", line)]
        ) from None
    if text.startswith("\ufeff"):
        text = text[1:]
    if not text.strip() or all(
        not line.strip() or line.lstrip().startswith("#") for line in text.splitlines()
    ):
        raise ExperimentError(file, [Issue("", "the file is empty")])
    loaded = load_text(text, file, p.suffix)
    if loaded.data is None:
        raise ExperimentError(file, [Issue("", "the file is empty")])
    return loaded
