"""Read experiment files (YAML, JSON, TOML) into plain data with line numbers.

YAML is composed into nodes with PyYAML's safe loader and converted here, so that only
plain data comes out (no ``!!python`` tags: only the standard scalar tags are accepted),
every mapping key gets its line number, duplicate keys are errors (PyYAML silently keeps
the last), and aliases cannot expand into a "billion laughs": the number of values an
alias expands to is capped.

Every parser here recurses once per level of nesting, so a file nested 500 deep would end
in ``RecursionError``. Nesting is capped at :data:`MAX_DEPTH` containers *while parsing*:
YAML's composer (in Python, over libyaml's events where PyYAML has libyaml) counts its
depth; JSON and TOML are pre-scanned for bracket depth outside strings and comments
(skipped when the file has too few brackets to reach the cap); TOML's dotted keys, which
nest without brackets, are measured after. The file is read through one descriptor that
must be a regular file (a FIFO or a device, whose ``stat()`` size is 0, is refused before
any read) and the read itself stops at :data:`MAX_FILE_BYTES` + 1 bytes.
"""

from __future__ import annotations

import json
import os
import re
import stat
import sys
from dataclasses import dataclass, field
from itertools import accumulate
from pathlib import Path
from typing import Any

import yaml

from hapticframe._errors import ExperimentError, Issue

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["LoadedFile", "load_file", "load_text", "read_regular_file"]

MAX_FILE_BYTES = 4 * 1024 * 1024
MAX_VALUES = 200_000  # values after alias expansion
MAX_DEPTH = 64  # containers nested in one another, the top-level mapping included

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


def _too_deep_message() -> str:
    return (f"nesting deeper than {MAX_DEPTH} levels: experiment files are shallow; "
            "is this the right file?")


class _TooDeep(Exception):
    """Raised by the composer at the first node nested deeper than :data:`MAX_DEPTH`."""

    def __init__(self, line: int) -> None:
        super().__init__(line)
        self.line = line


class _BoundedComposer(yaml.composer.Composer):
    """PyYAML's composer stopping at :data:`MAX_DEPTH`: the scanner and the parser keep
    explicit stacks; only composing recurses, once a level."""

    _depth = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        self._depth += 1
        try:
            # The node about to be composed has _depth - 1 containers around it.
            events: Any = self  # the parser's methods, from the class this is mixed into
            if self._depth > MAX_DEPTH and (
                events.check_event(yaml.SequenceStartEvent)
                or events.check_event(yaml.MappingStartEvent)
            ):
                raise _TooDeep(events.peek_event().start_mark.line + 1)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


if getattr(yaml, "__with_libyaml__", False):
    from yaml._yaml import CParser

    class _BoundedLoader(
        CParser, _BoundedComposer, yaml.constructor.SafeConstructor, yaml.resolver.Resolver
    ):
        """libyaml's events (ten times faster than PyYAML's scanner and parser) composed
        in Python, so that the depth is counted: libyaml's own composer recurses in C."""

        # CParser composes in C; these are the Python composer's.
        check_node = _BoundedComposer.check_node
        get_node = _BoundedComposer.get_node
        get_single_node = _BoundedComposer.get_single_node

        def __init__(self, stream: str) -> None:
            CParser.__init__(self, stream)
            _BoundedComposer.__init__(self)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)

else:  # pragma: no cover - PyYAML built without libyaml

    class _BoundedLoader(  # type: ignore[no-redef]
        yaml.reader.Reader, yaml.scanner.Scanner, yaml.parser.Parser, _BoundedComposer,
        yaml.constructor.SafeConstructor, yaml.resolver.Resolver,
    ):
        """PyYAML's safe loader with the bounded composer."""

        def __init__(self, stream: str) -> None:
            yaml.reader.Reader.__init__(self, stream)
            yaml.scanner.Scanner.__init__(self)
            yaml.parser.Parser.__init__(self)
            _BoundedComposer.__init__(self)
            yaml.constructor.SafeConstructor.__init__(self)
            yaml.resolver.Resolver.__init__(self)


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
        # The composer caps the file's nesting; aliases can nest deeper (an anchor inside
        # itself), so the cap holds here too. A container at ``depth`` is level depth + 1.
        if depth >= MAX_DEPTH and isinstance(node, (yaml.SequenceNode, yaml.MappingNode)):
            raise self.fail(node, _too_deep_message())
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
            except ValueError:  # an integer longer than Python converts (4300 digits)
                issue = Issue(path, _long_number_message(len(node.value)),
                              node.start_mark.line + 1)
                raise ExperimentError(self.file, [issue]) from None
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
        loader = _BoundedLoader(text)
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
    except _TooDeep as exc:
        raise ExperimentError(file, [Issue("", _too_deep_message(), exc.line)]) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        if "maximum nesting depth" in str(exc.problem):  # libyaml's own cap (1000 levels)
            raise ExperimentError(file, [Issue("", _too_deep_message(), line)]) from None
        message = " ".join(str(part) for part in (exc.context, exc.problem) if part)
        raise ExperimentError(file, [Issue("", f"YAML syntax error: {message}", line)]) from None
    except yaml.YAMLError as exc:
        raise ExperimentError(file, [Issue("", f"YAML error: {exc}")]) from None
    if node is None:
        return None, {}
    converter = _YamlConverter(file)
    data = converter.convert(node, "", 0)
    return data, converter.lines


#: A run of digits (TOML and YAML allow underscores between them) longer than Python
#: converts to an integer (``sys.get_int_max_str_digits()``, 4300 by default).
_LONG_NUMBER = re.compile(r"[0-9][0-9_]{4299,}")


def _long_number_message(digits: int) -> str:
    limit = getattr(sys, "get_int_max_str_digits", lambda: 4300)()
    return (f"a number of {digits} digits: Python reads integers of at most {limit} digits, "
            "and no setting needs one that long")


def _long_number_error(text: str, file: str) -> ExperimentError | None:
    """The located error for the first number too long to convert, or None."""
    match = _LONG_NUMBER.search(text)
    if match is None:
        return None
    line = text.count("\n", 0, match.start()) + 1
    digits = len(match.group().replace("_", ""))
    return ExperimentError(file, [Issue("", _long_number_message(digits), line)])


# Strings and comments, whose brackets are not structure. Each pattern matches whatever
# follows its opening quote (an unclosed string runs to the end of its line, where the
# parser stops anyway), so the scans never backtrack: they are linear in the text.
_JSON_SKIP = r'"[^"\\\n]*(?:\\[^\n]?[^"\\\n]*)*"?'  # a string
_TOML_SKIP = (
    r'"""[^"\\]*(?:(?:\\[\s\S]?|"(?!""))[^"\\]*)*(?:"{3,5})?'  # multi-line basic string
    r"|'''[^']*(?:'(?!'')[^']*)*(?:'{3,5})?"  # multi-line literal string
    r'|"[^"\\\n]*(?:\\[^\n]?[^"\\\n]*)*"?'  # basic string
    r"|'[^'\n]*'?"  # literal string
    r"|#[^\n]*"  # comment
)
_SKIP = {".json": re.compile(_JSON_SKIP), ".toml": re.compile(_TOML_SKIP)}
_TOKENS = {suffix: re.compile(rf"{pattern}|[\[\]{{}}]")
           for suffix, pattern in ((".json", _JSON_SKIP), (".toml", _TOML_SKIP))}
_NOT_BRACKETS = re.compile(r"[^\[\]{}]+")
_DEPTH_STEP = {"[": 1, "{": 1, "]": -1, "}": -1}


def _check_bracket_depth(text: str, suffix: str, file: str, implicit: int) -> None:
    """Refuse ``text`` if its brackets nest deeper than :data:`MAX_DEPTH` (before parsing).

    ``implicit`` counts the containers without brackets around everything (TOML's top-level
    table). The parsers stop at the first unbalanced closing bracket, so the running sum of
    openings minus closings up to there is the depth they would reach.
    """
    limit = MAX_DEPTH - implicit
    if text.count("[") + text.count("{") <= limit:
        return  # too few brackets to nest too deep: no scan
    skeleton = _NOT_BRACKETS.sub("", _SKIP[suffix].sub("", text))
    if max(accumulate(map(_DEPTH_STEP.__getitem__, skeleton)), default=0) <= limit:
        return
    depth = 0
    for match in _TOKENS[suffix].finditer(text):  # too deep: find the line where
        token = match.group()
        if token in ("[", "{"):
            depth += 1
            if depth > limit:
                line = text.count("\n", 0, match.start()) + 1
                raise ExperimentError(file, [Issue("", _too_deep_message(), line)])
        elif token in ("]", "}"):
            depth -= 1


def _check_data_depth(data: Any, file: str) -> None:
    """Refuse parsed data nested deeper than :data:`MAX_DEPTH`; iterative.

    TOML's dotted keys and table headers nest without brackets, and tomllib builds them
    without recursing, but what reads the data afterwards would.
    """
    stack: list[tuple[Any, str, int]] = [(data, "", 1)]
    while stack:
        value, path, depth = stack.pop()
        items = (value.items() if isinstance(value, dict)
                 else enumerate(value) if isinstance(value, list) else ())
        for key, child in items:
            if isinstance(child, (dict, list)):
                child_path = join_path(path, key)
                if depth >= MAX_DEPTH:
                    raise ExperimentError(file, [Issue(child_path, _too_deep_message())])
                stack.append((child, child_path, depth + 1))


def load_text(text: str, file: str, suffix: str) -> LoadedFile:
    """Parse ``text`` by the file suffix (``.yaml``/``.yml``, ``.json``, ``.toml``)."""
    suffix = suffix.lower()
    if suffix == ".json":
        _check_bracket_depth(text, suffix, file, implicit=0)
        try:
            data = json.loads(text, object_pairs_hook=_no_duplicate_pairs)
        except json.JSONDecodeError as exc:
            raise ExperimentError(
                file, [Issue("", f"JSON syntax error: {exc.msg}", exc.lineno)]
            ) from None
        except ValueError as exc:
            raise _long_number_error(text, file) or ExperimentError(
                file, [Issue("", str(exc))]
            ) from None
        try:  # JSON is YAML, so the YAML pass can tell line numbers.
            _, lines = _yaml_lines(text, file)
        except ExperimentError:
            lines = {}
        return LoadedFile(file, data, lines)
    if suffix == ".toml":
        _check_bracket_depth(text, suffix, file, implicit=1)
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ExperimentError(file, [Issue("", f"TOML syntax error: {exc}")]) from None
        except ValueError as exc:  # an integer longer than Python converts
            raise _long_number_error(text, file) or ExperimentError(
                file, [Issue("", f"TOML error: {exc}")]
            ) from None
        _check_data_depth(data, file)
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


_NOT_REGULAR = (
    (stat.S_ISDIR, "is a directory, not an experiment file"),
    (stat.S_ISFIFO, "is a FIFO (named pipe), not a regular file: give the path of a file"),
    (stat.S_ISCHR, "is a character device, not a regular file: give the path of a file"),
    (stat.S_ISBLK, "is a block device, not a regular file: give the path of a file"),
    (stat.S_ISSOCK, "is a socket, not a regular file: give the path of a file"),
)
# Opening a FIFO for reading blocks until a writer comes; without blocking it opens at
# once and fstat() tells what it is. The flag changes nothing for a regular file.
_OPEN_FLAGS = (os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
               | getattr(os, "O_BINARY", 0))
_CHUNK = 1 << 20


def read_regular_file(path: str | Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes.

    The file is opened once (a symbolic link is followed) and checked through that
    descriptor, so what is checked is what is read: a directory, FIFO, device or socket is
    refused before any read, and the read stops at ``limit`` + 1 bytes whatever ``stat()``
    said (a file that grows while read is refused too).

    Raises
    ------
    ExperimentError
        The path is missing, unreadable, not a regular file or larger than ``limit``; the
        one issue names the file and says why.
    """
    file = str(path)

    def refuse(message: str) -> ExperimentError:
        return ExperimentError(file, [Issue("", message)])

    try:
        fd = os.open(path, _OPEN_FLAGS)
    except FileNotFoundError:
        raise refuse("no such file") from None
    except IsADirectoryError:  # Windows opens no directories
        raise refuse(_NOT_REGULAR[0][1]) from None
    except OSError as exc:
        raise refuse(f"cannot read: {exc.strerror or exc}") from None
    try:
        mode = os.fstat(fd)
        if not stat.S_ISREG(mode.st_mode):
            reason = next((why for test, why in _NOT_REGULAR if test(mode.st_mode)),
                          "is not a regular file: give the path of a file")
            raise refuse(reason)
        if mode.st_size > limit:
            raise refuse(f"file is {mode.st_size} bytes; the limit is {limit}")
        chunks: list[bytes] = []
        size = 0
        while size <= limit:
            chunk = os.read(fd, min(_CHUNK, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise refuse(f"cannot read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if size > limit:
        raise refuse(f"file is more than {limit} bytes (it grew while read); the limit is {limit}")
    return b"".join(chunks)


def load_file(path: str | Path) -> LoadedFile:
    """Read and parse an experiment file, raising :class:`ExperimentError` when it is unusable."""
    p = Path(path)
    file = str(path)
    raw = read_regular_file(p)
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
