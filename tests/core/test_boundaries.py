"""The core never imports a plugin; no plugin reaches into another's private modules; the
public API is curated."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import hapticframe
import hapticframe.kinds
import hapticframe.testing

CORE = Path(hapticframe.__file__).parent
PLUGINS = CORE.parent / "plugins"


def _imported_names(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


# "hapticframe_x._private" (a module path, optionally ":attribute" as in a factory string).
_PRIVATE_PATH = re.compile(r"(hapticframe_\w+)((?:\.\w+)*)(?::[\w.]+)?")


def _private_references(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every import or module-path string naming a plugin's private module.

    Absolute imports (``import hapticframe_x._y``, ``from hapticframe_x._y import z``,
    ``from hapticframe_x import _y``) and string constants that are a whole module path
    (``importlib.import_module("hapticframe_x._y")``, ``factory="hapticframe_x._y:Cls"``).
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[tuple[int, str]] = []

    def check(line: int, dotted: str) -> None:
        parts = dotted.split(".")
        if parts[0].startswith("hapticframe_") and any(p.startswith("_") for p in parts[1:]):
            found.append((line, dotted))

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                check(node.lineno, alias.name)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            before = len(found)
            check(node.lineno, node.module)
            if len(found) == before:  # ``from hapticframe_x import _y``
                for alias in node.names:
                    check(node.lineno, f"{node.module}.{alias.name}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            match = _PRIVATE_PATH.fullmatch(node.value)
            if match:
                check(node.lineno, match.group(1) + match.group(2))
    return sorted(found)


def _owner(path: Path) -> str | None:
    """The plugin package a file belongs to (None for the core)."""
    try:
        return path.relative_to(PLUGINS).parts[0]
    except ValueError:
        return None


def test_no_package_imports_another_plugins_private_modules():
    offenders = []
    for path in [*CORE.rglob("*.py"), *PLUGINS.rglob("*.py")]:
        owner = _owner(path)
        for line, dotted in _private_references(path):
            if dotted.split(".")[0] != owner:
                offenders.append(f"{path.relative_to(CORE.parent)}:{line} uses {dotted}")
    assert not offenders, (
        "use the other plugin's public API (its __init__ __all__) instead:\n" + "\n".join(offenders)
    )


def test_the_private_module_check_catches_each_form(tmp_path):
    source = tmp_path / "offender.py"
    source.write_text(
        "import hapticframe_a._b\n"
        "from hapticframe_a._b import c\n"
        "from hapticframe_a import _b\n"
        "import importlib; importlib.import_module('hapticframe_a._b')\n"
        "FACTORY = 'hapticframe_a._b:Thing'\n"
        "from hapticframe_a import public\n"
        "DOC = 'see hapticframe_a._b for details'\n",
        encoding="utf-8",
    )
    assert [line for line, _ in _private_references(source)] == [1, 2, 3, 4, 5]


def test_core_never_imports_a_plugin_package():
    plugin_packages = {p.name for p in PLUGINS.iterdir() if p.is_dir()} | {"hapticframe_"}
    offenders = []
    for path in CORE.rglob("*.py"):
        for name in _imported_names(path):
            top = name.split(".")[0]
            if top in plugin_packages or top.startswith("hapticframe_"):
                offenders.append(f"{path.relative_to(CORE.parent)} imports {name}")
    assert not offenders, offenders


def test_bundled_plugins_use_only_the_public_api():
    offenders = []
    for path in PLUGINS.rglob("*.py"):
        for name in _imported_names(path):
            parts = name.split(".")
            if parts[0] == "hapticframe" and any(p.startswith("_") for p in parts[1:]):
                offenders.append(f"{path.relative_to(PLUGINS)} imports private {name}")
    assert not offenders, offenders


def test_public_names_are_sorted_and_exist():
    for module in (hapticframe, hapticframe.kinds, hapticframe.testing):
        names = module.__all__
        assert list(names) == sorted(names), f"{module.__name__}.__all__ is not sorted"
        assert len(set(names)) == len(names)
        for name in names:
            assert hasattr(module, name), f"{module.__name__}.{name}"
